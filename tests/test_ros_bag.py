"""ROS 2 bags in and out (fidlearn.ros.read_bag, BagWriter, ``fidlearn locate BAG -o OUT.mcap``), on bags built
here from rendered frames, so the poses are compared with the truth."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from helpers import assert_user_error, ctrl_c_as_a_terminal_gives_it
from helpers import run_cli as run
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Writer

import fidlearn
from fidlearn import data_path
from fidlearn.errors import CameraError, RosFormatError, TrackingError
from fidlearn.filtering._so3 import rotation_from_xyzw
from fidlearn.images import Frame
from fidlearn.ros import BagWriter, read_bag, ros_covariance, ros_pose, write_image_bag
from fidlearn.ros._messages import build, typestore

MAP = fidlearn.MarkerMap.load(data_path("world_map.json"))
CAM = fidlearn.Camera.from_fov(60, (640, 480))
T0 = 1_700_000_000_000_000_000
#: A drive of 24 frames 50 ms apart, of which these are recorded: 150 ms and 50 ms apart by turns.
INDEX = [0, 3, 4, 7, 8, 11, 12, 15, 16, 19, 20, 23]
N = len(INDEX)


@pytest.fixture(scope="module")
def drive():
    return fidlearn.render_trajectory(MAP, CAM, n_frames=24, frames_to_render=INDEX)


def stamps(n=N):
    """The recorded frames' header stamps (ns), with a fraction of a second that a float would round."""
    return [T0 + 123_456_789 + 50_000_000 * k for k in INDEX[:n]]


def messages(path, topic):
    with AnyReader([path], default_typestore=typestore()) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:  # rosbags reads every topic when given none
            return []
        return [(t, reader.deserialize(raw, c.msgtype)) for c, t, raw in reader.messages(connections=conns)]


def angle_deg(R1, R2):
    return float(np.degrees(np.arccos(np.clip((np.trace(R1.T @ R2) - 1) / 2, -1, 1))))


# -- bags in ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("encoding", ["bgr8", "rgb8", "mono8"])
def test_images_stamps_and_camera_come_back_exactly(tmp_path, drive, encoding):
    images = [cv2.cvtColor(im, cv2.COLOR_GRAY2BGR) if im.ndim == 2 else im for im in drive.images[:3]]
    images[0] = images[0].copy()
    images[0][:40, :60] = (255, 0, 0)  # a blue patch: a swapped red and blue would show
    bag = write_image_bag(tmp_path / "in.mcap", images, CAM, stamps(3), encoding=encoding)
    frames = read_bag(bag)
    assert frames.image_topic == "/camera/image_raw"
    assert frames.camera_info_topic == "/camera/camera_info"
    got = list(frames)
    assert [f.stamp for f in got] == stamps(3)
    for f, want in zip(got, images):
        expect = cv2.cvtColor(want, cv2.COLOR_BGR2GRAY) if encoding == "mono8" else want
        np.testing.assert_array_equal(f.image, expect)
        np.testing.assert_array_equal(f.camera.K, CAM.K)
        assert (f.camera.width, f.camera.height) == (640, 480)
    assert frames.frame_id == "camera"


def test_bayer_mosaic_is_demosaiced_to_the_right_colours(tmp_path):
    image = np.zeros((120, 160, 3), np.uint8)
    image[:, :80] = (30, 200, 90)  # B, G, R
    image[:, 80:] = (220, 40, 160)
    bag = write_image_bag(tmp_path / "bayer.mcap", [image], None, [T0], encoding="bayer_rggb8")
    (frame,) = read_bag(bag)
    assert frame.camera is None
    np.testing.assert_allclose(frame.image[60, 40].astype(int), (30, 200, 90), atol=2)
    np.testing.assert_allclose(frame.image[60, 120].astype(int), (220, 40, 160), atol=2)


def _driver_bag(path, images, *, storage="sqlite3", info=None, step_pad=8, topics=("/cam/image_raw",)):
    """A bag as a camera driver records it (rosbags' own writer, rows padded to a longer step)."""
    from rosbags.rosbag2 import StoragePlugin

    store = typestore()
    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    with Writer(path, version=8, storage_plugin=plugin) as w:
        conns = {t: w.add_connection(t, "sensor_msgs/msg/Image", typestore=store) for t in topics}
        ci = w.add_connection("/cam/camera_info", "sensor_msgs/msg/CameraInfo", typestore=store) if info else None
        for k, image in enumerate(images):
            h, wd = image.shape[:2]
            rows = np.zeros((h, wd * 3 + step_pad), np.uint8)
            rows[:, : wd * 3] = image.reshape(h, -1)
            header = {"stamp": {"sec": 1_700_000_000 + k, "nanosec": 5}, "frame_id": "cam_optical"}
            msg = build("sensor_msgs/msg/Image", {"header": header, "height": h, "width": wd, "encoding": "bgr8",
                                                  "step": wd * 3 + step_pad, "data": rows.reshape(-1)})  # fmt: skip
            for t in topics:
                w.write(conns[t], T0 + k, store.serialize_cdr(msg, "sensor_msgs/msg/Image"))
            if ci is not None:
                w.write(ci, T0 + k, store.serialize_cdr(build("sensor_msgs/msg/CameraInfo", {"header": header, **info}),
                                                        "sensor_msgs/msg/CameraInfo"))  # fmt: skip
    return path


def _info(model="plumb_bob", d=(0.1, -0.05, 0.001, 0.002, 0.01), k=None):
    k = CAM.K.reshape(-1) if k is None else k
    return {"width": 640, "height": 480, "distortion_model": model, "d": list(d), "k": list(k)}


def test_a_driver_bag_folder_with_sqlite3_storage_and_padded_rows(tmp_path, drive):
    images = [cv2.cvtColor(im, cv2.COLOR_GRAY2BGR) for im in drive.images[:2]]
    bag = _driver_bag(tmp_path / "driver", images, info=_info())
    frames = read_bag(bag)
    got = list(frames)
    assert [f.stamp for f in got] == [1_700_000_000_000_000_005, 1_700_000_001_000_000_005]
    np.testing.assert_array_equal(got[1].image, images[1])
    np.testing.assert_allclose(np.ravel(got[0].camera.dist), [0.1, -0.05, 0.001, 0.002, 0.01])
    assert frames.frame_id == "cam_optical"
    assert frames.camera_info_topic == "/cam/camera_info"


def test_a_fisheye_camera_written_to_a_bag_reads_back_as_itself(tmp_path):
    """equidistant has 4 coefficients of its own: they were padded to plumb_bob's 5 and refused on reading."""
    pinhole = fidlearn.Camera.from_fov(60, (64, 48))
    fish = fidlearn.Camera(pinhole.K, [0.01, -0.002, 0.001, -0.0003], (64, 48), model="fisheye")
    write_image_bag(tmp_path / "fish.mcap", [np.zeros((48, 64, 3), np.uint8)], fish, [1])
    (frame,) = read_bag(tmp_path / "fish.mcap")
    assert frame.camera.model == "fisheye"
    assert frame.camera.dist.tolist() == fish.dist.tolist()
    assert (frame.camera.K == fish.K).all()


def test_a_stamp_past_a_ros_times_int32_seconds_is_refused_by_name(tmp_path):
    T = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 0, 90), [1000, 150, 250])
    bag = BagWriter(tmp_path / "late.mcap")
    with pytest.raises(RosFormatError, match=r"0 to 2\^31 s .a ROS time's seconds are an int32"):
        bag.write(2**31 * 10**9, fidlearn.TrackedPose(0.5, T, np.eye(6), "measured"))
    bag.abort()  # as leaving its with block by the error does
    with pytest.raises(RosFormatError, match="int32"):
        write_image_bag(tmp_path / "late2.mcap", [np.zeros((8, 8), np.uint8)], None, [2**31 * 10**9])
    assert not list(tmp_path.iterdir())


def test_rational_polynomial_is_read_and_an_unknown_model_refused(tmp_path, drive):
    images = [cv2.cvtColor(drive.images[0], cv2.COLOR_GRAY2BGR)]
    rational = _info("rational_polynomial", d=(0.1, -0.05, 0.0, 0.0, 0.01, 0.02, 0.0, 0.0))
    (frame,) = read_bag(_driver_bag(tmp_path / "r", images, info=rational))
    assert np.ravel(frame.camera.dist).size == 8
    with pytest.raises(RosFormatError, match="distortion_model 'plumb_bobcat'"):
        read_bag(_driver_bag(tmp_path / "u", images, info=_info("plumb_bobcat")))
    with pytest.raises(CameraError, match="not calibrated"):
        read_bag(_driver_bag(tmp_path / "z", images, info=_info(k=[0.0] * 9)))


def test_topics_chosen_and_refused(tmp_path, drive):
    images = [cv2.cvtColor(drive.images[0], cv2.COLOR_GRAY2BGR)]
    bag = _driver_bag(tmp_path / "two", images, topics=("/left/image_raw", "/right/image_raw"))
    with pytest.raises(RosFormatError, match=r"2 image topics \(/left/image_raw, /right/image_raw\); choose one"):
        read_bag(bag)
    assert read_bag(bag, image_topic="/right/image_raw").image_topic == "/right/image_raw"
    with pytest.raises(RosFormatError, match="no topic '/middle'"):
        read_bag(bag, image_topic="/middle")


def test_broken_and_empty_bags_are_clear_errors(tmp_path, drive):
    with pytest.raises(RosFormatError, match="no such bag"):
        read_bag(tmp_path / "none.mcap")
    (tmp_path / "folder").mkdir()
    with pytest.raises(RosFormatError, match="holds metadata.yaml"):
        read_bag(tmp_path / "folder")
    (tmp_path / "junk.mcap").write_bytes(b"not an mcap file at all" * 10)
    with pytest.raises(RosFormatError, match="cannot read this ROS 2 bag"):
        read_bag(tmp_path / "junk.mcap")
    whole = write_image_bag(tmp_path / "whole.mcap", [drive.images[0]] * 2, CAM, stamps(2)).read_bytes()
    (tmp_path / "cut.mcap").write_bytes(whole[: len(whole) // 2])
    with pytest.raises(RosFormatError, match="cut.mcap: cannot read this ROS 2 bag"):
        list(read_bag(tmp_path / "cut.mcap"))
    with BagWriter(tmp_path / "poses.mcap") as w:
        w.write(T0, fidlearn.filtering.TrackedPose(0.0, np.eye(4), np.eye(6), "measured"))
    with pytest.raises(RosFormatError, match="no sensor_msgs/msg/Image or CompressedImage topic"):
        read_bag(tmp_path / "poses.mcap")


def test_a_broken_bag_leaves_no_file_open(tmp_path):
    """A file that is not a bag is refused and closed at once, not left for the garbage collector to close with
    a ResourceWarning (rosbags 0.11.0 itself kept the file of a reader that failed to open)."""
    import gc
    import warnings

    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"\x89MCAP0\r\n" + b"\0" * 50)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always", ResourceWarning)
        for _ in range(3):
            with pytest.raises(RosFormatError, match="cannot read this ROS 2 bag"):
                read_bag(junk)
        gc.collect()
    assert [str(w.message) for w in seen if issubclass(w.category, ResourceWarning)] == []


def test_frames_of_a_compressed_bag_locate_at_the_true_poses(tmp_path, drive):
    bag = write_image_bag(tmp_path / "c", drive.images, CAM, stamps(), image_topic="/cam/image_raw/compressed")
    frames = read_bag(bag)
    assert frames.camera_info_topic == "/cam/camera_info"
    assert len(frames) == N
    run = [Frame(f"c#{k}", f.image, "c", "video") for k, f in enumerate(frames)]
    times = [(s - stamps()[0]) / 1e9 for s in stamps()]
    steps = list(fidlearn.track(run, MAP, CAM, times=times))
    assert [s.t_s for s in steps] == times == pytest.approx([0.05 * k for k in INDEX], abs=1e-12)
    errors = []
    for k, (step, T) in enumerate(zip(steps, drive.T_world_camera)):
        errors.append(np.linalg.norm(step.tracked.T_world_camera[:3, 3] - T[:3, 3]))
        assert errors[-1] < 4 * np.sqrt(np.trace(step.tracked.covariance[3:, 3:]))  # within the track's own spread
        angle = np.radians(angle_deg(step.tracked.T_world_camera[:3, :3], T[:3, :3]))
        assert angle < 4 * np.sqrt(np.trace(step.tracked.covariance[:3, :3]))
        # the second frame, 150 ms after the first, is 1.5 degrees off: the track starts at rest and the frames
        # state about 1.3 degrees each, so one step does not tell the turn; within 0.8 degrees after
        assert np.degrees(angle) < (2.0 if k == 1 else 1.0)
    assert errors[-1] < 10.0
    with pytest.raises(TrackingError, match="frame 1's time 0.000000000 s is not after"):
        list(fidlearn.track(run[:2], MAP, CAM, times=[0.0, 0.0]))


# -- bags out ---------------------------------------------------------------------------------------
def test_a_written_bag_reads_back_with_every_field_as_written(tmp_path):
    T = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 5, 80), [1200.0, -300.0, 250.0])
    cov = np.diag([1e-4, 2e-4, 3e-4, 4.0, 9.0, 16.0])
    cov[3, 4] = cov[4, 3] = 1.5
    mount = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 0, -90), [0.0, -300.0, -200.0])
    tracked = fidlearn.filtering.TrackedPose(0.25, T, cov, "measured", T_world_base=T @ mount, base_covariance=cov,
                                             velocity_mm_s=np.array([100.0, 0, 0]),
                                             angular_velocity_rad_s=np.array([0, 0, 0.5]))  # fmt: skip
    stamp = T0 + 987_654_321
    with BagWriter(tmp_path / "out.mcap", MAP, T_camera_base=mount, camera_frame="cam_optical") as w:
        w.write(stamp, tracked)
    want = ros_pose(tracked, body="base_link")
    (t, pose), = messages(tmp_path / "out.mcap", "/fidlearn/pose")  # fmt: skip
    assert t == stamp
    assert (pose.header.stamp.sec, pose.header.stamp.nanosec) == divmod(stamp, 10**9)
    assert pose.header.frame_id == "map"
    p, q = pose.pose.pose.position, pose.pose.pose.orientation
    assert [p.x, p.y, p.z] == list(want["pose"]["pose"]["position"].values())
    assert [q.x, q.y, q.z, q.w] == list(want["pose"]["pose"]["orientation"].values())
    assert list(pose.pose.covariance) == ros_covariance(cov)
    (_, odo), = messages(tmp_path / "out.mcap", "/fidlearn/odometry")  # fmt: skip
    assert odo.child_frame_id == "base_link"
    assert list(odo.pose.covariance) == ros_covariance(cov)
    base = T @ mount  # the base's velocity in its own axes: the camera's plus w x (base - camera)
    v = base[:3, :3].T @ (np.array([100.0, 0, 0]) + np.cross([0, 0, 0.5], base[:3, 3] - T[:3, 3])) / 1000
    tw = odo.twist.twist
    np.testing.assert_allclose([tw.linear.x, tw.linear.y, tw.linear.z], v, atol=1e-12)
    np.testing.assert_allclose([tw.angular.x, tw.angular.y, tw.angular.z], base[:3, :3].T @ [0, 0, 0.5], atol=1e-12)
    assert odo.twist.covariance[0] == -1.0
    (_, tf), = messages(tmp_path / "out.mcap", "/tf")  # fmt: skip
    (tr,) = tf.transforms
    assert (tr.header.frame_id, tr.child_frame_id) == ("map", "base_link")
    np.testing.assert_allclose([tr.transform.translation.x, tr.transform.translation.y], base[:2, 3] / 1000)
    (_, static), = messages(tmp_path / "out.mcap", "/tf_static")  # fmt: skip
    (st,) = static.transforms
    assert (st.header.frame_id, st.child_frame_id) == ("base_link", "cam_optical")
    r = st.transform.rotation
    R = rotation_from_xyzw(np.array([r.x, r.y, r.z, r.w]))
    np.testing.assert_allclose(R, np.linalg.inv(mount)[:3, :3], atol=1e-12)
    (_, arr), = messages(tmp_path / "out.mcap", "/fidlearn/markers")  # fmt: skip
    cubes = {m.id: m for m in arr.markers if m.ns == "fidlearn_markers"}
    assert sorted(cubes) == MAP.ids
    for mid, m in cubes.items():
        centre = MAP.marker_corners(mid).mean(axis=0) / 1000
        np.testing.assert_allclose([m.pose.position.x, m.pose.position.y, m.pose.position.z], centre, atol=1e-12)
        assert m.scale.x == pytest.approx(MAP.marker_size_mm / 1000)
    assert [m.text for m in arr.markers if m.ns == "fidlearn_marker_ids"] == [str(i) for i in MAP.ids]


def test_a_bag_is_whole_or_absent_and_never_written_over(tmp_path):
    pose = fidlearn.filtering.TrackedPose(0.0, np.eye(4), np.eye(6), "measured")

    def interrupted():
        with BagWriter(tmp_path / "cut.mcap") as w:
            w.write(T0, pose)
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        interrupted()
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "keep.mcap").write_bytes(b"mine")
    with pytest.raises(RosFormatError, match="keep.mcap exists; a bag is never written over"):
        BagWriter(tmp_path / "keep.mcap")
    assert (tmp_path / "keep.mcap").read_bytes() == b"mine"
    with BagWriter(tmp_path / "folder") as w:
        w.write(T0, pose)
    assert sorted(p.name for p in (tmp_path / "folder").iterdir()) == ["folder.mcap", "metadata.yaml"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder", "keep.mcap"]  # no hidden folder left


# -- the command line ---------------------------------------------------------------------------------
def test_locate_a_bag_writes_poses_at_the_image_stamps(tmp_path, capsys, drive):
    bag = write_image_bag(tmp_path / "in.mcap", drive.images, CAM, stamps())
    code, out, err = run(capsys, "locate", bag, "--map", data_path("world_map.json"), "-o", tmp_path / "out.mcap",
                         "--json", tmp_path / "poses.jsonl")  # fmt: skip
    assert code == 0, err
    assert f"{N} poses written to {tmp_path / 'out.mcap'}" in out
    records = [json.loads(line) for line in (tmp_path / "poses.jsonl").read_text().splitlines()]
    got = messages(tmp_path / "out.mcap", "/fidlearn/pose")
    assert [t for t, _ in got] == stamps()
    for (_, msg), rec, truth in zip(got, records, drive.T_world_camera):
        p = msg.pose.pose.position
        assert [p.x * 1000, p.y * 1000, p.z * 1000] == pytest.approx(rec["position_mm"], abs=1e-9)
        assert np.linalg.norm(np.array([p.x, p.y, p.z]) * 1000 - truth[:3, 3]) < 40.0
    tf = messages(tmp_path / "out.mcap", "/tf")
    assert {m.transforms[0].child_frame_id for _, m in tf} == {"camera"}
    assert messages(tmp_path / "out.mcap", "/fidlearn/odometry") == []


def test_locate_track_a_bag_on_its_stamps(tmp_path, capsys, drive):
    bag = write_image_bag(tmp_path / "in", drive.images, CAM, stamps())
    code, out, err = run(capsys, "locate", bag, "--map", data_path("world_map.json"), "--track", "-o",
                         tmp_path / "track.mcap")  # fmt: skip
    assert code == 0, err
    rows = [line.split() for line in out.splitlines() if line.startswith("in#")]
    times = [(s - stamps()[0]) / 1e9 for s in stamps()]
    assert [float(r[1]) for r in rows] == pytest.approx(times, abs=1e-3)
    odo = messages(tmp_path / "track.mcap", "/fidlearn/odometry")
    assert [t for t, _ in odo] == stamps()
    last = odo[-1][1].pose.pose.position
    assert np.linalg.norm(np.array([last.x, last.y, last.z]) * 1000 - drive.T_world_camera[-1][:3, 3]) < 15.0


def odometry_samples(drive):
    """The camera's true path as a robot's odometry (the camera is the base), in an odom frame of its own."""
    T_odom_world = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(0, 0, 35), [400.0, -250.0, 0.0])
    return [(s, T_odom_world @ T) for s, T in zip(stamps(), drive.T_world_camera)]


def test_locate_track_with_the_bags_odometry_topic_as_with_the_same_csv(tmp_path, capsys, drive):
    images = [im.copy() for im in drive.images]
    for k in (6, 7, 8):  # the markers out of sight: only the odometry carries the track
        images[k][:] = 128
    samples = odometry_samples(drive)
    bag = write_image_bag(tmp_path / "in.mcap", images, CAM, stamps(), odometry=samples)
    odometry = fidlearn.ros.read_bag_odometry(bag, "/odom")
    assert odometry.times_s == pytest.approx([(s - stamps()[0]) / 1e9 for s in stamps()], abs=1e-12)
    np.testing.assert_allclose(odometry.poses[5], samples[5][1], atol=1e-6)
    csv = tmp_path / "odom.csv"
    rows = ["t_s,x_m,y_m,z_m,qx,qy,qz,qw"]
    for t, T in zip(odometry.times_s, odometry.poses):
        q = ros_pose(fidlearn.TrackedPose(0.0, T, np.eye(6), "measured"))["pose"]["pose"]
        rows.append(",".join(repr(float(v)) for v in [t, *q["position"].values(), *q["orientation"].values()]))
    csv.write_text("\n".join(rows) + "\n")
    m = data_path("world_map.json")
    outs = {}
    for name, extra in (("topic", ["--odometry-topic", "/odom"]), ("csv", ["--odometry", csv])):
        out = tmp_path / f"{name}.jsonl"
        code, text, err = run(capsys, "locate", bag, "--map", m, "--track", "-o", out, *extra)
        assert code == 0, err
        assert "odometry scale learnt from the poses" in text
        outs[name] = [json.loads(line) for line in out.read_text().splitlines()]
    for a, b in zip(outs["topic"], outs["csv"]):
        assert a["position_mm"] == pytest.approx(b["position_mm"], abs=1e-6)
    bridged = outs["topic"][8]
    assert bridged["status"] != "measured"
    assert np.linalg.norm(np.array(bridged["position_mm"]) - drive.T_world_camera[8][:3, 3]) < 15.0
    # without the odometry the gap is bridged by the motion model alone, farther from the truth
    code, _, err = run(capsys, "locate", bag, "--map", m, "--track", "-o", tmp_path / "none.jsonl")
    alone = [json.loads(line) for line in (tmp_path / "none.jsonl").read_text().splitlines()][8]
    assert np.linalg.norm(np.array(alone["position_mm"]) - drive.T_world_camera[8][:3, 3]) > np.linalg.norm(
        np.array(bridged["position_mm"]) - drive.T_world_camera[8][:3, 3]
    )


def test_the_bags_odometry_topic_refused_clearly(tmp_path, capsys, drive):
    m = data_path("world_map.json")
    bag = write_image_bag(tmp_path / "in.mcap", drive.images[:2], CAM, stamps(2))
    assert_user_error(*run(capsys, "locate", bag, "--map", m, "--track", "--odometry-topic", "/odom")[::2],
                      "no topic '/odom' in this bag; its Odometry topics: none")  # fmt: skip
    one = write_image_bag(tmp_path / "one.mcap", drive.images[:2], CAM, stamps(2), odometry=odometry_samples(drive)[:1])
    assert_user_error(*run(capsys, "locate", one, "--map", m, "--track", "--odometry-topic", "/odom")[::2],
                      "the motion needs two")  # fmt: skip
    assert_user_error(*run(capsys, "locate", bag, "--map", m, "--odometry-topic", "/odom")[::2], "add --track")
    (tmp_path / "o.csv").write_text("t_s,x_m,y_m,z_m,qx,qy,qz,qw\n")
    assert_user_error(*run(capsys, "locate", bag, "--map", m, "--track", "--odometry-topic", "/odom",
                           "--odometry", tmp_path / "o.csv")[::2], "give the odometry once")  # fmt: skip
    pic = data_path("scenes", "scene_00.png")
    cam = data_path("scenes", "camera.json")
    assert_user_error(*run(capsys, "locate", pic, "--camera", cam, "--map", m, "--odometry-topic", "/odom")[::2],
                      "chooses a topic of a ROS 2 bag")  # fmt: skip
    with pytest.raises(RosFormatError, match="no topic '/nope'"):
        fidlearn.ros.read_bag_odometry(one, "/nope")


def test_locate_bag_user_errors(tmp_path, capsys, drive):
    m = data_path("world_map.json")
    bag = write_image_bag(tmp_path / "in.mcap", drive.images[:2], CAM, stamps(2))
    small = fidlearn.Camera.from_fov(60, (320, 240))
    small.save(tmp_path / "small.json")
    assert_user_error(*run(capsys, "locate", bag, "--map", m, "--camera", tmp_path / "small.json")[::2],
                      "not the bag's: the CameraInfo is for 640x480, the camera given for 320x240")  # fmt: skip
    nocam = write_image_bag(tmp_path / "nocam.mcap", drive.images[:1], None, [T0])
    assert_user_error(*run(capsys, "locate", nocam, "--map", m, "--camera", tmp_path / "small.json")[::2],
                      "nocam.mcap#0: the image is 640x480, --camera is for 320x240")  # fmt: skip
    assert_user_error(*run(capsys, "locate", nocam, "--map", m)[::2], "no CameraInfo beside /camera/image_raw")
    (tmp_path / "out.mcap").write_bytes(b"mine")
    assert_user_error(*run(capsys, "locate", bag, "--map", m, "-o", tmp_path / "out.mcap")[::2], "exists")
    assert (tmp_path / "out.mcap").read_bytes() == b"mine"
    assert_user_error(*run(capsys, "locate", bag, "--map", m, "-o", bag)[::2], "is one of the inputs")
    pic = data_path("scenes", "scene_00.png")
    cam = data_path("scenes", "camera.json")
    assert_user_error(*run(capsys, "locate", pic, "--camera", cam, "--map", m, "-o", tmp_path / "o.mcap")[::2],
                      "give a ROS 2 bag as input")  # fmt: skip
    assert_user_error(*run(capsys, "locate", bag, pic, "--map", m)[::2], "a ROS 2 bag is read alone")
    (tmp_path / "junk.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\0" * 50)
    assert_user_error(*run(capsys, "locate", tmp_path / "junk.mcap", "--map", m)[::2], "cannot read this ROS 2 bag")
    assert not (tmp_path / "o.mcap").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "in.mcap",
        "junk.mcap",
        "nocam.mcap",
        "out.mcap",
        "small.json",
    ]


# -- the live view ------------------------------------------------------------------------------------
@pytest.mark.parametrize("track", [False, True])
def test_live_view_serves_the_poses_the_command_writes(tmp_path, drive, track):
    """``locate BAG --live 0``: a WebSocket client sees the channels, decodes the poses, equal to the output's
    (--json's without --track, -o OUT.mcap's with it)."""
    import os
    import signal
    import struct
    import subprocess
    import sys

    import websocket

    bag = write_image_bag(tmp_path / "in.mcap", drive.images, CAM, stamps())
    env = {**os.environ, "PYTHONPATH": str(Path(fidlearn.__file__).parent.parent)}
    cmd = [sys.executable, "-m", "fidlearn", "locate", str(bag), "--map", str(data_path("world_map.json")),
           "--live", "0"]  # fmt: skip
    cmd += ["--track", "-o", str(tmp_path / "out.mcap")] if track else ["--json", str(tmp_path / "poses.jsonl")]
    with ctrl_c_as_a_terminal_gives_it():  # a background test run would start the command with Ctrl-C ignored
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path)
    try:
        line = proc.stdout.readline()
        while line and not line.startswith("live view: ws://127.0.0.1:"):  # the table's header may come first
            line = proc.stdout.readline()
        assert line, "no live view"
        ws = websocket.create_connection(line.split()[2], subprotocols=["foxglove.sdk.v1"], timeout=20)
        channels = {}
        while not channels:
            msg = json.loads(ws.recv())
            if msg["op"] == "advertise":
                channels = {c["id"]: c for c in msg["channels"]}
        topics = {c["topic"]: c for c in channels.values()}
        assert topics["/fidlearn/pose"]["schemaName"] == "geometry_msgs/msg/PoseWithCovarianceStamped"
        assert topics["/fidlearn/pose"]["encoding"] == "cdr"
        assert {"/fidlearn/image/compressed", "/fidlearn/path", "/fidlearn/markers", "/tf"} <= set(topics)
        subs = [{"id": k, "channelId": cid} for k, cid in enumerate(channels)]
        ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
        got = {}
        while min(len(got.get(t, [])) for t in ("/fidlearn/pose", "/fidlearn/path")) < N:  # a path follows each pose
            data = ws.recv()
            if isinstance(data, bytes) and data[0] == 1:
                sub, log_time = struct.unpack_from("<IQ", data, 1)
                topic = channels[subs[sub]["channelId"]]["topic"]
                got.setdefault(topic, []).append((log_time, data[13:]))
        while "open at" not in line:  # the run is done: --json is written
            line = proc.stdout.readline()
            assert line, "the command ended before its live view"
        ws.close()
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            code = proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise
    assert code == 0, proc.stderr.read()
    store = typestore()
    if track:
        written = messages(tmp_path / "out.mcap", "/fidlearn/pose")
        want = [[m.pose.pose.position.x * 1000, m.pose.pose.position.y * 1000, m.pose.pose.position.z * 1000]
                for _, m in written]  # fmt: skip
    else:
        want = [json.loads(x)["position_mm"] for x in (tmp_path / "poses.jsonl").read_text().splitlines()]
    assert len(want) == N
    assert [t for t, _ in got["/fidlearn/pose"]] == stamps()
    for (_, raw), position in zip(got["/fidlearn/pose"], want):
        msg = store.deserialize_cdr(raw, "geometry_msgs/msg/PoseWithCovarianceStamped")
        p = msg.pose.pose.position
        assert [p.x * 1000, p.y * 1000, p.z * 1000] == pytest.approx(position, abs=1e-9)
        assert msg.pose.covariance[0] > 0
    assert ("/fidlearn/odometry" in got) == track
    image = store.deserialize_cdr(got["/fidlearn/image/compressed"][0][1], "sensor_msgs/msg/CompressedImage")
    assert cv2.imdecode(np.asarray(image.data), cv2.IMREAD_COLOR).shape == (480, 640, 3)
    path = store.deserialize_cdr(got["/fidlearn/path"][-1][1], "nav_msgs/msg/Path")
    assert len(path.poses) == N
