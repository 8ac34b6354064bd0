"""The pose tracker and smoother (fidlearn.filtering) against known answers: poses projected from known places."""

from __future__ import annotations

import numpy as np
import pytest

import fidlearn
from fidlearn import frames
from fidlearn.detection import Detection
from fidlearn.errors import FidlearnError, TrackingError
from fidlearn.filtering import GATE_CHI2, MAX_REJECTIONS, PoseTracker, TrackedPose, smooth
from fidlearn.filtering._so3 import exp_so3, log_so3, quaternion_xyzw, rotation_from_xyzw

MAP = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
CAM = fidlearn.Camera.from_fov(60, (640, 480))
FACING_WALL = frames.rotation_from_rpy_deg(-90, 0, 90)  # camera z along world -X


def pose_at(x, y=150.0, z=250.0):
    return frames.make_transform(FACING_WALL, [x, y, z])


def dets(T, rng, noise_px, ids=None):
    return [
        Detection(i, CAM.project(c, T) + rng.normal(0, noise_px, (4, 2)))
        for i, c in MAP.corners().items()
        if ids is None or i in ids
    ]


def test_so3_exp_log_round_trip_and_quaternions():
    rng = np.random.default_rng(1)
    for _ in range(50):
        w = rng.normal(size=3)
        w *= rng.uniform(0, np.pi - 1e-4) / np.linalg.norm(w)
        R = exp_so3(w)
        np.testing.assert_allclose(log_so3(R), w, atol=1e-9)
        q = quaternion_xyzw(R)
        assert q[3] >= 0
        np.testing.assert_allclose(rotation_from_xyzw(q), R, atol=1e-12)
    np.testing.assert_allclose(np.abs(log_so3(frames.rot_z(np.pi))), [0, 0, np.pi], atol=1e-9)
    # hand-computed: 90 deg about z is (0, 0, sin 45, cos 45)
    np.testing.assert_allclose(quaternion_xyzw(frames.rot_z(np.pi / 2)), [0, 0, 2**-0.5, 2**-0.5], atol=1e-15)


def test_static_camera_converges_to_the_truth():
    T = pose_at(700.0)
    rng = np.random.default_rng(0)
    tracker = PoseTracker(MAP, CAM, process_noise=(1.0, 0.001), corner_sigma_px=0.3)
    frame_err, track_err = [], []
    for k in range(90):
        out = tracker.update(dets(T, rng, 0.3), k / 30)
        frame_err.append(np.linalg.norm(out.pose.position_mm - T[:3, 3]))
        track_err.append(np.linalg.norm(out.position_mm - T[:3, 3]))
        assert out.status == ("started" if k == 0 else "measured")
    rms = lambda e: float(np.sqrt(np.mean(np.square(e[-30:]))))  # noqa: E731
    assert track_err[-1] < 3.0  # one frame alone: about 8 mm
    assert rms(track_err) < 0.4 * rms(frame_err)
    assert frames.rotation_angle_deg(out.T_world_camera[:3, :3], T[:3, :3]) < 0.3  # one frame alone: about 0.7 degrees
    assert out.position_ellipsoid_contains(T[:3, 3], 0.99)


def _ambiguous_far_pose(rng):
    """One marker far away, seen nearly face-on (14 degrees to the side, so that one of the two planar solutions is
    the right one and the other is a flip of about 30 degrees). Returns (truth, pose) with pose.ambiguous."""
    c0 = MAP.marker_corners(0).mean(axis=0)
    for _ in range(50):
        T = fidlearn.look_at(c0 + [3000.0, 700.0, 0.0], c0)
        p = fidlearn.estimate_pose(dets(T, rng, 0.5, ids={0}), MAP, CAM, corner_sigma_px=0.5)
        if p.ambiguous and p.alternative is not None:  # the right solution first, whichever IPPE ranked first
            return T, p if _nearer(p, p.alternative, T) else _flipped(p)
    raise AssertionError("no ambiguous view found")


def _flipped(p: fidlearn.Pose) -> fidlearn.Pose:
    """The same frame with its two solutions swapped: the first-ranked one is the wrong one."""
    a = p.alternative
    return fidlearn.Pose(
        a.T_world_camera, p.marker_ids, p.residuals_px, p.reprojection_rms_px, p.covariance, p.corner_sigma_px,
        ambiguous=True, alternative=fidlearn.Pose(
            p.T_world_camera, p.marker_ids, p.residuals_px, p.reprojection_rms_px, a.covariance, p.corner_sigma_px
        ),
    )  # fmt: skip


def test_an_injected_flip_never_reaches_the_output():
    rng = np.random.default_rng(3)
    T, p = _ambiguous_far_pose(rng)
    truth_to_alt = np.linalg.norm(p.alternative.position_mm - T[:3, 3])
    flip_deg = frames.rotation_angle_deg(p.alternative.T_world_camera[:3, :3], T[:3, :3])
    assert truth_to_alt > 500  # a flip is far from the truth
    assert flip_deg > 10
    tracker = PoseTracker(MAP, CAM, process_noise=(1.0, 0.001), corner_sigma_px=0.3)
    for k in range(20):  # the track starts on all three markers at the same pose (their exact corners)
        tracker.update(dets(T, rng, 0.0), k / 30)
    turned_back = 0
    for k in range(20, 60):
        _, pk = _ambiguous_far_pose(rng)
        pk = _flipped(pk) if k % 2 else pk  # every other frame the wrong solution is ranked first
        out = tracker.update(pk, k / 30)
        turned_back += out.flip_resolved
        assert np.linalg.norm(out.position_mm - T[:3, 3]) < 0.25 * truth_to_alt
        assert frames.rotation_angle_deg(out.T_world_camera[:3, :3], T[:3, :3]) < 0.25 * flip_deg
    assert turned_back >= 15  # at least the 20 injected flips, less the few frames whose own noise ranks them


def _nearer(a: fidlearn.Pose, b: fidlearn.Pose, T) -> bool:
    """Whether pose a's rotation is nearer the truth T than pose b's."""
    return frames.rotation_angle_deg(a.T_world_camera[:3, :3], T[:3, :3]) < frames.rotation_angle_deg(
        b.T_world_camera[:3, :3], T[:3, :3]
    )


def test_a_frame_far_off_is_rejected_and_said_so():
    T = pose_at(700.0)
    rng = np.random.default_rng(5)
    tracker = PoseTracker(MAP, CAM, process_noise=(1.0, 0.001), corner_sigma_px=0.3)
    for k in range(30):
        tracker.update(dets(T, rng, 0.3), k / 30)
    off = fidlearn.estimate_pose(dets(pose_at(900.0, 300.0), rng, 0.3), MAP, CAM, corner_sigma_px=0.3)
    out = tracker.update(off, 1.0)
    assert out.rejected
    assert out.status == "rejected"
    assert "chi-square" in out.reason
    assert out.mahalanobis2 > GATE_CHI2
    assert np.linalg.norm(out.position_mm - T[:3, 3]) < 3.0


def _drive(n, speed_mm_s=300.0, dt=1 / 30):
    """A camera driving along the wall (world +Y) at constant speed: true poses and times."""
    return [pose_at(900.0, -200.0 + speed_mm_s * k * dt) for k in range(n)], [k * dt for k in range(n)]


@pytest.mark.parametrize("scale", [1.02, 0.97])
def test_a_gap_is_bridged_by_the_motion_model_and_by_odometry_whose_scale_the_track_learns(scale):
    poses, times = _drive(150)
    for use_odometry in (False, True):
        rng = np.random.default_rng(7)
        tracker = PoseTracker(MAP, CAM, process_noise=(50.0, 0.05), corner_sigma_px=0.3)
        worst = 0.0
        for k, (T, t) in enumerate(zip(poses, times)):
            gap = 60 <= k < 120  # 2 s without a frame
            odo = None
            if use_odometry and k > 0:
                rel = frames.invert_transform(poses[k - 1]) @ T
                rel[:3, 3] *= scale  # wheels that report every step 2 % too far (or 3 % too short)
                odo = (rel, np.diag([1e-6] * 3 + [0.5**2] * 3))
            out = tracker.update(None if gap else dets(T, rng, 0.3), t, odometry=odo)
            if k == 59 and use_odometry:  # 2 s of poses and odometry: the scale is learnt (prior: 1 +- 0.05)
                assert abs(out.odometry_scale - 1 / scale) < 3 * out.odometry_scale_std < 0.03, out.odometry_scale
            if gap:
                assert out.status == ("odometry" if use_odometry else "predicted")
                worst = max(worst, np.linalg.norm(out.position_mm - T[:3, 3]))
                assert out.position_ellipsoid_contains(T[:3, 3], 0.99)
        # 2 s at 300 mm/s: 600 mm driven; the raw odometry would be 12-18 mm off at the end
        assert worst < (9.0 if use_odometry else 30.0)


def test_predict_leaves_the_track_alone():
    poses, times = _drive(40)
    rng = np.random.default_rng(2)
    tracker = PoseTracker(MAP, CAM, process_noise=(50.0, 0.05), corner_sigma_px=0.3)
    for T, t in zip(poses, times):
        last = tracker.update(dets(T, rng, 0.3), t)
    ahead = tracker.predict(times[-1] + 0.5)
    assert ahead.status == "predicted"
    np.testing.assert_allclose(ahead.position_mm, last.position_mm + 0.5 * last.velocity_mm_s, atol=1e-9)
    assert abs(ahead.position_mm[1] - (poses[-1][1, 3] + 150.0)) < 20.0  # 0.5 s at 300 mm/s
    assert (ahead.position_std_mm > last.position_std_mm).all()
    assert tracker.last is last
    assert tracker.predict(times[-1]).t_s == times[-1]


def test_the_mount_gives_the_base_pose_and_its_covariance():
    T_camera_base = frames.make_transform(frames.rotation_from_rpy_deg(90, -90, 0), [0.0, 300.0, -100.0])
    rng = np.random.default_rng(4)
    tracker = PoseTracker(MAP, CAM, T_camera_base=T_camera_base, corner_sigma_px=0.3)
    out = tracker.update(dets(pose_at(800.0), rng, 0.3), 0.0)
    np.testing.assert_allclose(out.T_world_base, out.T_world_camera @ T_camera_base, atol=1e-12)
    # numeric check of the base covariance: perturb the camera pose along each error coordinate
    J = np.zeros((6, 6))
    base0 = out.T_world_base
    for j in range(6):
        d = np.zeros(6)
        d[j] = 1e-6
        Tc = out.T_world_camera.copy()
        Tc[:3, :3] = exp_so3(d[:3]) @ Tc[:3, :3]
        Tc[:3, 3] += d[3:]
        Tb = Tc @ T_camera_base
        J[:, j] = np.r_[log_so3(Tb[:3, :3] @ base0[:3, :3].T), Tb[:3, 3] - base0[:3, 3]] / 1e-6
    np.testing.assert_allclose(out.base_covariance, J @ out.covariance @ J.T, rtol=1e-4, atol=1e-9)


def test_smooth_beats_the_filter_and_keeps_the_truth():
    poses, times = _drive(90)
    rng = np.random.default_rng(9)
    measured = [
        None if 30 <= k < 40 else fidlearn.estimate_pose(dets(T, rng, 0.5), MAP, CAM, corner_sigma_px=0.5)
        for k, T in enumerate(poses)
    ]
    tracker = PoseTracker(MAP, CAM, process_noise=(50.0, 0.05))
    filtered = [tracker.update(p, t) for p, t in zip(measured, times)]
    smoothed = smooth(measured, times, process_noise=(50.0, 0.05))
    assert len(smoothed) == 90
    assert all(s.status == "smoothed" for s in smoothed)
    err = lambda out: np.sqrt(np.mean([np.sum((o.position_mm - T[:3, 3]) ** 2) for o, T in zip(out, poses)]))  # noqa: E731
    assert err(smoothed) < 0.8 * err(filtered)
    # exact measurements: the smoother returns the truth
    exact = [fidlearn.estimate_pose(dets(T, rng, 0.0), MAP, CAM, corner_sigma_px=0.01) for T in poses[:10]]
    for o, T in zip(smooth(exact, times[:10]), poses[:10]):
        np.testing.assert_allclose(o.position_mm, T[:3, 3], atol=0.05)


@pytest.mark.parametrize(
    ("call", "fragment"),
    [
        (lambda t: t.update(None, 0.0), "no pose yet"),
        (lambda t: t.predict(1.0), "nothing to predict"),
        (lambda t: t.update("frame.png", 0.0), "update() takes"),
        (lambda t: t.update(_pose(), float("nan")), "finite time"),
        (lambda t: (t.update(_pose(), 1.0), t.update(_pose(), 0.5)), "before the last frame"),
        (lambda t: (t.update(_pose(), 0.0), t.update(None, 0.1, odometry=np.eye(4))), "odometry must be a pair"),
        (lambda t: (t.update(_pose(), 0.0), t.update(None, 0.1, odometry=(np.eye(4), np.eye(3)))), "6x6"),
        (lambda t: (t.update(_pose(), 0.0), t.update(None, 0.1, odometry=(np.eye(4), -np.eye(6)))), "semi-definite"),
    ],
)
def test_bad_inputs_say_what_is_wrong(call, fragment):
    with pytest.raises(TrackingError, match=fragment.replace("(", r"\(").replace(")", r"\)")):
        call(PoseTracker(MAP, CAM))


def test_bad_options_are_fidlearn_errors():
    with pytest.raises(TrackingError, match="process_noise"):
        PoseTracker(MAP, CAM, process_noise=(0, 1))
    with pytest.raises(FidlearnError, match="T_camera_base"):
        PoseTracker(MAP, CAM, T_camera_base=np.ones((4, 4)))
    with pytest.raises(FidlearnError):
        PoseTracker(CAM, MAP)
    with pytest.raises(TrackingError, match="one entry per frame"):
        smooth([_pose()], [0.0, 1.0])
    with pytest.raises(TrackingError, match="odometry must be a list with one entry per frame, got int"):
        smooth([_pose(), _pose()], [0.0, 1.0], odometry=5)
    with pytest.raises(TrackingError, match="nothing to smooth"):
        smooth([None, None], [0.0, 1.0])


def test_tracked_pose_reads_well():
    out = PoseTracker(MAP, CAM).update(_pose(), 0.0)
    assert isinstance(out, TrackedPose)
    assert out.measured
    assert not out.rejected
    assert repr(out).startswith("TrackedPose(t_s=0.000, started, position_mm=[700.0, 150.0, 250.0]")


def _pose():
    return fidlearn.estimate_pose(dets(pose_at(700.0), np.random.default_rng(0), 0.0), MAP, CAM, corner_sigma_px=0.3)


def test_a_track_that_keeps_disagreeing_restarts():
    rng = np.random.default_rng(6)
    tracker = PoseTracker(MAP, CAM, process_noise=(1.0, 0.001), corner_sigma_px=0.3)
    for k in range(20):
        tracker.update(dets(pose_at(700.0), rng, 0.3), k / 30)
    moved = pose_at(900.0, 300.0)  # the camera was carried elsewhere unseen
    statuses = [tracker.update(dets(moved, rng, 0.3), (20 + k) / 30).status for k in range(MAX_REJECTIONS + 2)]
    assert statuses == ["rejected"] * MAX_REJECTIONS + ["restarted", "measured"]
    assert np.linalg.norm(tracker.last.position_mm - moved[:3, 3]) < 40.0  # two frames, each about 15 mm off


def test_frames_as_images():
    drive = fidlearn.render_trajectory(MAP, CAM, n_frames=40, frames_to_render=range(30, 36))
    tracker = PoseTracker(MAP, CAM)
    for k, (image, T) in enumerate(zip(drive.images, drive.T_world_camera)):
        out = tracker.update(image if k != 3 else np.full_like(image, 128), k / 30)  # frame 3: a blank wall
        assert out.status == ("started" if k == 0 else "predicted" if k == 3 else "measured")
        assert np.linalg.norm(out.position_mm - T[:3, 3]) < (20.0 if k == 3 else 10.0)
    assert "no marker" in tracker.update(np.full_like(image, 128), 0.3).reason
