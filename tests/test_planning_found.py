"""Markers near the detector's limit are missed now and then: the prediction mixes the subsets found."""

import math

import numpy as np
import pytest

import fidlearn
from fidlearn import Camera, MarkerMap, look_at, predict_accuracy, render_scene
from fidlearn.errors import FidlearnError, PoseError
from fidlearn.planning import finding

RENDER = {"blur_px": 0.5, "noise_std_gray": 1.2, "gradient": 0.2}
VGA = Camera.from_fov(60, (640, 480))


def wall(top_left: dict[int, list[float]], size_mm: float = 80.0) -> MarkerMap:
    markers = {str(i): {"translation": t, "rotation": [0, 0, 0]} for i, t in top_left.items()}
    return MarkerMap.from_dict({"units": "mm", "marker_size_mm": size_mm, "markers": markers})


def test_the_subsets_and_their_chances_are_those_of_independent_markers():
    subsets, pose = finding.found_subsets({1: 0.5, 2: 0.8, 3: 0.99})
    # marker 3 is sure; 1 and 2 in or out: four subsets, none empty
    assert dict((tuple(ids), w) for w, ids in subsets) == pytest.approx(
        {(3,): 0.1, (1, 3): 0.1, (2, 3): 0.4, (1, 2, 3): 0.4}
    )
    assert pose == pytest.approx(1 - 0.5 * 0.2 * 0.01)
    subsets, pose = finding.found_subsets({1: 0.5, 2: 0.5})  # nothing found a quarter of the time
    assert pose == pytest.approx(0.75)
    assert dict((tuple(ids), w) for w, ids in subsets) == pytest.approx({(1,): 1 / 3, (2,): 1 / 3, (1, 2): 1 / 3})


def test_many_uncertain_markers_are_drawn_and_the_same_every_time():
    found = {i: 0.3 for i in range(10)}
    a, pose = finding.found_subsets(found)
    assert len(a) == finding.MAX_SUBSETS
    assert all(ids for _, ids in a)
    assert sum(w for w, _ in a) == pytest.approx(1.0)
    assert pose == pytest.approx(1 - 0.7**10)
    assert finding.found_subsets(found)[0] == a


def test_the_chance_of_finding_a_marker_is_refused_for_a_non_number():
    with pytest.raises(PoseError, match="side_px"):
        finding.found_probability(float("nan"))
    assert finding.found_probability(finding.HALF_FOUND_SIDE_PX) == pytest.approx((1 - finding.MISSED) / 2)


def test_small_markers_on_a_wall_are_found_as_often_as_predicted():
    # 12 markers, 11 to 13 px across at 640x480: predicted found about half the time
    rng = np.random.default_rng(5)
    world = wall({i: [0.0, -600.0 + 100.0 * i + 10 * (i // 4), 300.0 + 150.0 * (i % 4)] for i in range(12)})
    predicted, found = [], 0
    for k in range(8):
        T = look_at([3300.0 + 100 * rng.uniform(), 300 * rng.uniform(-1, 1), 600.0], [0.0, 0.0, 550.0])
        p = predict_accuracy(world, VGA, T)
        image = render_scene(world, VGA, T, seed=k, **RENDER).image
        got = {d.id for d in fidlearn.detect_markers(image, ids=world.ids)}
        predicted += [p.found_probability[i] for i in p.marker_ids]
        found += sum(i in got for i in p.marker_ids)
    n, q = len(predicted), float(np.mean(predicted))
    assert 0.2 < q < 0.8  # the markers are near the limit
    assert abs(found / n - q) < 3 * math.sqrt(q * (1 - q) / n) + 0.05


#: Eight 80 mm markers on a wall seen from 3.8 m at 640x480: five large enough for the detector, all
#: near its limit (10 to 11 px). The detector finds only one, whose pose is the other planar solution,
#: 5.4 m from the truth; predicted with all five found, the error was 265 times the predicted RMS.
FAR_WALL = {
    0: [0.0, 133.933894434, 253.641310496],
    1: [0.0, 82.310070514, 567.032578015],
    2: [0.0, 76.781458642, 789.762832864],
    3: [0.0, 214.342916621, 997.782038454],
    4: [0.0, -411.997123639, 850.284335002],
    5: [0.0, -106.688415715, 826.646016848],
    6: [0.0, 470.135008554, 993.598550385],
    7: [0.0, -280.749786043, 562.350616831],
}
FAR_T = np.array(
    [
        [-0.653628438273077, -0.014830326797907618, -0.7566702888892662, 2905.789858878424],
        [0.7568156081111821, -0.012808302630264553, -0.6535029324364453, 2510.5873303270446],
        [0.0, -0.9998079859607039, 0.019595693639194778, 496.9193849423606],
        [0.0, 0.0, 0.0, 1.0],
    ]
)


def test_a_far_wall_whose_markers_may_be_missed_has_the_lone_markers_flip_in_its_tail():
    world = wall(FAR_WALL)
    p = predict_accuracy(world, VGA, FAR_T)
    assert len(p.marker_ids) == 5
    assert all(0.1 < p.found_probability[i] < 0.6 for i in p.marker_ids)
    assert p.flip_probability > 0.01
    assert p.flip_likely
    errors = []
    for k in range(2):
        image = render_scene(world, VGA, FAR_T, seed=10_000 + k, **RENDER).image
        try:
            errors.append(float(np.linalg.norm(fidlearn.locate(image, world, VGA).position_mm - FAR_T[:3, 3])))
        except FidlearnError:
            continue  # no marker found: predicted too (pose_probability < 1)
    assert p.pose_probability < 1.0
    assert errors
    assert max(errors) > 1000.0
    assert max(errors) < 5 * p.position_rms_mm  # and the predicted RMS holds it (265 times it before)
    assert p.position_p90_mm > 10 * p.position_error_mm
