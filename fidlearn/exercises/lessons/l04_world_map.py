"""Lesson 04: Markers and the world map.

One builder per question, in the order the notebook asks them; each draws its numbers from
its own generator (``_rng("04", learner, "qN")``), so a learner's variant of one question
does not depend on the others.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ... import frames
from ...markermap import MarkerMap, MarkerPlacement
from .._engine import Question, QuestionText, _AnswerError
from .._parsers import (
    _array,
    _close,
    _cmp_array,
    _corner_order,
    _parts,
    _winding_message,
)
from .._scenery import (
    _WALL_YAW,
    _rng,
    _wall_translation,
)

NUMBER = "04"
TOPIC = "world_map"
TITLE = "Markers and the world map"
INTRO = """
    From a tape measure to corners: placements in feet, a map file in centimetres, a marker on the
    floor, and the winding order TL, TR, BR, BL that detection and the map must share.
    """


def _map_diagnosis(got: MarkerMap, want: MarkerMap) -> str | None:
    """What differs between two maps, in words (None if their corners agree within 0.5 mm)."""
    missing = sorted(set(want.ids) - set(got.ids))
    extra = sorted(set(got.ids) - set(want.ids))
    if missing:
        return f"your map has no marker {missing[0]}; it needs ids {want.ids}"
    if extra:
        return f"your map has marker {extra[0]}, which is not on the walls; it needs ids {want.ids}"
    if abs(got.marker_size_mm - want.marker_size_mm) > 0.01:
        return (
            f"marker_size_mm is {got.marker_size_mm:g}, the markers are {want.marker_size_mm:g} mm (the black "
            "square's side, in mm whatever the map's units)"
        )
    for mid in want.ids:
        g, w = got.marker_corners(mid), want.marker_corners(mid)
        if np.abs(g - w).max() <= 0.5:
            continue
        if np.abs(g[0] * 10 - w[0]).max() <= 1:
            return (
                f"marker {mid} is 10x too close to the origin: the positions are in cm, so the map's units "
                'must be "cm"'
            )
        if np.abs(g[0] / 10 - w[0]).max() <= 1:
            return (
                f'marker {mid} is 10x too far: the positions are in cm; say "units": "cm" (the library converts to mm)'
            )
        if np.abs(g[0] - w[0]).max() <= 0.5:
            n_got, n_want = got.normal(mid), want.normal(mid)
            return (
                f"marker {mid}: its top-left corner is right but it faces {np.round(n_got, 3).tolist()}; on its "
                "wall it must face "
                f"{np.round(n_want, 3).tolist()} (into the room): check its yaw"
            )
        return (
            f"marker {mid}: its top-left corner is {np.round(g[0], 1).tolist()} mm, expected "
            f"{np.round(w[0], 1).tolist()} "
            "mm"
        )
    return None


#: q1's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q1: QuestionText = {
    "title": "Corners from a placement in feet",
    "task": """
        Marker `marker_id` hangs on the wall named in `wall`. The map gives its `placement`: "translation"
        is the world position of its TOP-LEFT corner in `units` (feet!), "rotation" is
        [roll, pitch, yaw] in degrees, R = Rz(yaw) @ Ry(pitch) @ Rx(roll), applied about that corner.
        With rotation [0, 0, 0] a marker faces +X and TR = TL + s*Y, BL = TL - s*Z (s the side).
        Write code that computes its 4 corners in world mm, a (4, 3) array in the order
        TL, TR, BR, BL (do not use MarkerMap: that is what you are rebuilding).
        """,
    "hint": [
        "Two steps: bring the placement into mm, then walk from the top-left corner along the marker's own axes.",
        (
            "The rotation (roll, pitch, yaw in degrees) turns the marker's frame into the world; in that frame the "
            "marker's right is +y and its up is +z, so TR is one side to the right of TL, BR one side right and one "
            "down, BL one side down (notebook 04)."
        ),
    ],
    "solution": """
        p = q1.inputs.placement
        s = q1.inputs.marker_size_mm
        TL = np.asarray(p["translation"], dtype=float) * 304.8        # feet -> mm
        R = frames.rotation_from_rpy_deg(*p["rotation"])
        offsets = s * np.array([[0, 0, 0], [0, 1, 0], [0, 1, -1], [0, 0, -1]])   # TL, TR, BR, BL
        q1.answer = TL + offsets @ R.T
        """,
    "level": "easy",
}


def _q1(learner: str) -> Question:
    """q1: Corners from a placement in feet."""
    rng = _rng("04", learner, "q1")
    wall = str(rng.choice(list(_WALL_YAW)))
    t_ft = _wall_translation(rng, wall, 0.25, (-4, 4), (2, 6), per_ft=1.0)
    size = float(rng.choice([80, 100, 120, 150]))
    mid = int(rng.integers(0, 50))
    placement = {"translation": t_ft, "rotation": [0, 0, _WALL_YAW[wall]]}
    mm = MarkerMap.from_dict({str(mid): placement}, units="ft", marker_size_mm=size)
    C = mm.marker_corners(mid)
    local = np.array([[0, 0, 0], [0, 1, 0], [0, 1, -1], [0, 0, -1]], dtype=float) * size
    C_unconverted = local @ frames.rotation_from_rpy_deg(0, 0, _WALL_YAW[wall]).T + np.asarray(t_ft)
    C_no_yaw = local + np.asarray(t_ft) * 304.8

    def winding(a):
        order = _corner_order(a, C, 0.5)
        return order is not None and order != ("TL", "TR", "BR", "BL")

    return Question(
        "q1",
        inputs={"marker_id": mid, "wall": wall, "placement": placement, "units": "ft", "marker_size_mm": size},
        expected=C,
        parse=_array(
            (4, 3),
            "the corners",
            {
                (3, 4): "one ROW per corner: transpose it",
                (4, 2): "these are world corners: 3 coordinates (x, y, z) each",
            },
        ),
        compare=_cmp_array(0.5, " mm"),
        wrong=[
            (
                lambda a: _close(a, C_unconverted, 0.5) or _close(a, C / 304.8, 0.01),
                "the translation is in feet: multiply it by 304.8 to get mm (your values are 304.8x too small)",
            ),
            (winding, lambda a: _winding_message(_corner_order(a, C, 0.5))),
            (
                lambda a: _close(a, C_no_yaw, 0.5),
                f"the rotation was left out: on the {wall} wall the marker's right (TL->TR) is R @ [0, 1, 0], not +Y",
            ),
            (
                lambda a: _close(a[0], C[0], 0.5),
                (
                    "the top-left corner is right; the others are TL + R @ (s * [0, 1, 0]) (TR), TL + R @ (s "
                    "* [0, 1, -1]) (BR) and TL + R @ (s * [0, 0, -1]) (BL)"
                ),
            ),
        ],
        **_Q1,
    )


#: q2's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q2: QuestionText = {
    "title": "Write the world map",
    "task": """
        You measured 4 markers with a tape in centimetres: `measured` lists each marker's id, its
        wall and the world position of its top-left corner in cm. Markers on a wall face into the
        room; `wall_yaw_deg` gives the yaw that turns a marker (which faces +X at yaw 0) to face
        into the room from each wall. Write code that builds the map as a dict in fidlearn's full
        map-file layout, {"units": ..., "marker_size_mm": ..., "dictionary": ..., "markers":
        {"<id>": {"translation": [x, y, z], "rotation": [roll, pitch, yaw]}}}, which
        fidlearn.MarkerMap.from_dict must load to the right corners.
        """,
    "hint": (
        'Keep the numbers in cm and say "units": "cm"; the rotation of each marker is [0, 0, wall_yaw_deg[wall]]; '
        'the keys of "markers" are the ids as strings.'
    ),
    "solution": """
        q2.answer = {
            "units": "cm",
            "marker_size_mm": q2.inputs.marker_size_mm,
            "dictionary": q2.inputs.dictionary,
            "markers": {
                str(m["id"]): {"translation": m["top_left_cm"], "rotation": [0, 0, q2.inputs.wall_yaw_deg[m["wall"]]]}
                for m in q2.inputs.measured
            },
        }
        """,
    "level": "medium",
}


def _q2(learner: str) -> Question:
    """q2: Write the world map."""
    rng = _rng("04", learner, "q2")
    size2 = float(rng.choice([80, 100, 150]))
    ids = sorted(int(i) for i in rng.choice(50, size=4, replace=False))
    walls = [str(w) for w in rng.choice(list(_WALL_YAW), size=4)]
    walls[0], walls[1] = "north", "east"
    room_cm = {"north": 0.0, "south": 487.68, "west": -182.88, "east": 182.88}
    measured: list[dict[str, Any]] = []  # the map file's entries
    for i, w in zip(ids, walls):
        along = float(np.round(rng.uniform(-150, 150)))
        z = float(np.round(rng.uniform(60, 200)))
        # along y on the north and south walls; along x, from the middle of the room, on the others
        tl = [room_cm[w], along, z] if w in ("north", "south") else [243.84 + along, room_cm[w], z]
        measured.append({"id": i, "wall": w, "top_left_cm": tl})
    want = MarkerMap(
        {
            m["id"]: MarkerPlacement(
                m["id"], tuple(v * 10 for v in m["top_left_cm"]), (0.0, 0.0, float(_WALL_YAW[m["wall"]]))
            )
            for m in measured
        },
        size2,
        dictionary="ARUCO_ORIGINAL",
        units="cm",
    )

    def parse_map(answer):
        if isinstance(answer, MarkerMap):
            return answer
        if isinstance(answer, dict):
            try:
                return MarkerMap.from_dict(answer, source="your map")
            except Exception as exc:  # the library's message says what to fix
                raise _AnswerError(f"MarkerMap.from_dict cannot read your dict: {exc}") from None
        raise _AnswerError(f"give a dict in the map-file layout (or a MarkerMap), got {type(answer).__name__}")

    return Question(
        "q2",
        inputs={
            "measured": measured,
            "wall_yaw_deg": dict(_WALL_YAW),
            "marker_size_mm": size2,
            "dictionary": "ARUCO_ORIGINAL",
        },
        expected=want,
        parse=parse_map,
        compare=_map_diagnosis,
        **_Q2,
    )


#: q3's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q3: QuestionText = {
    "title": "A marker on the floor",
    "task": """
        A marker lies flat on the floor, printed face up. Its own "up" direction (from its bottom
        edge to its top edge, BL -> TL) points along the world axis `up_direction` (as a vector:
        `up_vector`).
        Write code that finds its map rotation [roll, pitch, yaw] in degrees (R = Rz(yaw) @ Ry(pitch)
        @ Rx(roll); at [0, 0, 0] a marker faces +X with its up along +Z and its right, TL -> TR,
        along +Y). Hint of a method: build the 3x3 matrix whose columns are the marker's face
        normal, right and up directions in the world, then convert it.
        """,
    "hint": [
        (
            "A rotation matrix's columns are where the marker's own axes point in the world: its face normal, its"
            " right and its up."
        ),
        (
            "On the floor, face up, the normal is +Z; the up is given; the right is up x normal (right-handed, as"
            " at rotation 0). The map wants that matrix as roll, pitch, yaw in degrees: frames has the "
            "conversion."
        ),
    ],
    "solution": """
        up = np.asarray(q3.inputs.up_vector, dtype=float)
        normal = np.array([0.0, 0.0, 1.0])          # face up, off the floor
        right = np.cross(up, normal)                 # at rotation 0: up (Z) x normal (X) = right (Y)
        R = np.column_stack([normal, right, up])
        q3.answer = frames.rpy_deg_from_rotation(R)
        """,
    "level": "medium",
}


def _q3_mistakes(rotated_about_normal, R3, normal, R_of, up) -> list:
    """The mistakes q3 names: (detector, message) pairs, in the order they are tried."""
    return [
        (
            lambda a: frames.rotation_angle_deg(R_of(np.degrees(a)), R3) <= 0.5,
            "those look like radians: map rotations are in degrees (np.degrees)",
        ),
        (
            lambda a: R_of(a)[:, 0] @ normal < -0.999,
            "your marker faces DOWN, into the floor: its normal (the first column of R) must be +Z",
        ),
        (
            lambda a: R_of(a)[:, 0] @ normal > 0.999 and R_of(a)[:, 2] @ up < -0.999,
            (
                "the marker is upside down: TL and BR swap places; its up (the third column of R) must point "
                "along up_direction"
            ),
        ),
        (
            rotated_about_normal,
            (
                "the face is right but the marker is turned by 90 degrees about its normal: the corners would "
                "start at another corner (the winding order shifts); its up (third column of R) must point "
                "along up_direction"
            ),
        ),
    ]


def _q3(learner: str) -> Question:
    """q3: A marker on the floor."""
    rng = _rng("04", learner, "q3")
    dirs = {"+X": (1, 0, 0), "-X": (-1, 0, 0), "+Y": (0, 1, 0), "-Y": (0, -1, 0)}
    up_name = str(rng.choice(list(dirs)))
    up = np.array(dirs[up_name], dtype=float)
    normal = np.array([0.0, 0.0, 1.0])
    R3 = np.column_stack([normal, np.cross(up, normal), up])

    def R_of(a):
        return frames.rotation_from_rpy_deg(*a)

    def rotated_about_normal(a):
        ang = frames.rotation_angle_deg(R_of(a), R3)
        return R_of(a)[:, 0] @ normal > 0.999 and ang > 1 and abs(ang - 180) > 1

    return Question(
        "q3",
        inputs={"up_direction": up_name, "up_vector": up},
        expected=R3,
        parse=_array(
            (3,),
            "[roll, pitch, yaw]",
            {
                (
                    3,
                    3,
                ): (
                    "that is a rotation matrix; the map wants [roll, pitch, yaw] in degrees: "
                    "frames.rpy_deg_from_rotation(R)"
                )
            },
        ),
        compare=lambda a, b: (
            None
            if frames.rotation_angle_deg(R_of(a), b) <= 0.5
            else f"with your angles the marker faces {np.round(R_of(a)[:, 0], 3).tolist()} with its up along "
            f"{np.round(R_of(a)[:, 2], 3).tolist()}; "
            f"it should face {normal.tolist()} (up off the floor) with its up along {up.tolist()}"
        ),
        wrong=_q3_mistakes(rotated_about_normal, R3, normal, R_of, up),
        **_Q3,
    )


#: q4's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q4: QuestionText = {
    "title": "Centre and facing direction",
    "task": """
        `marker_map` is a fidlearn MarkerMap. For marker `marker_id`, write code that computes its
        centre in world mm (3,) and the unit normal (3,) of its printed face, pointing out of the
        face (towards the room, where a camera can see it). Use only its corners
        (marker_map.marker_corners(id), TL, TR, BR, BL). Answer {"center_mm": ..., "normal": ...}.
        """,
    "hint": [
        "The centre is where the four corners balance; the normal is perpendicular to two edges of the face.",
        (
            "Take two edges that start at one corner, in the order right then up, and their cross product; the "
            "right-hand rule decides which side it points to. Make it unit length."
        ),
    ],
    "solution": """
        c = q4.inputs.marker_map.marker_corners(q4.inputs.marker_id)
        TL, TR, BR, BL = c
        n = np.cross(TR - TL, TL - BL)
        q4.answer = {"center_mm": c.mean(axis=0), "normal": n / np.linalg.norm(n)}
        """,
    "level": "medium",
}


def _q4(learner: str) -> Question:
    """q4: Centre and facing direction."""
    rng = _rng("04", learner, "q4")
    placements = {}
    for i, w in enumerate(["north", "west", "east", "south"]):
        mid4 = 10 + i
        placements[mid4] = MarkerPlacement(
            mid4,
            tuple(_wall_translation(rng, w, 10.0, (-1200, 1200), (600, 1800), per_ft=304.8)),
            (0.0, 0.0, float(_WALL_YAW[w])),
        )
    m4 = MarkerMap(placements, float(rng.choice([80, 100, 150])), dictionary="ARUCO_ORIGINAL", units="mm")
    ask = int(rng.choice(m4.ids[1:]))
    centre = m4.marker_corners(ask).mean(axis=0)
    nrm = m4.normal(ask)
    c4 = m4.marker_corners(ask)
    return Question(
        "q4",
        inputs={"marker_map": m4, "marker_id": ask},
        expected={"center_mm": centre, "normal": nrm},
        parse=_parts(center_mm=_array((3,), "center_mm"), normal=_array((3,), "normal")),
        compare=lambda a, b: (
            _cmp_array(0.5, " mm")(a["center_mm"], b["center_mm"]) or _cmp_array(0.01)(a["normal"], b["normal"])
        ),
        wrong=[
            (
                lambda a: _close(a["center_mm"], c4[0], 0.5),
                "center_mm is the top-left corner: the centre is the mean of the 4 corners",
            ),
            (
                lambda a: _close(a["normal"], -nrm, 0.01),
                (
                    "your normal points INTO the wall: with corners TL, TR, BR, BL the outward normal is (TR "
                    "- TL) x (TL - BL), right x up"
                ),
            ),
            (
                lambda a: (
                    abs(np.linalg.norm(a["normal"]) - 1) > 0.01
                    and _close(a["normal"] / np.linalg.norm(a["normal"]), nrm, 0.01)
                ),
                "the direction is right; divide by its length to make it a unit vector",
            ),
        ],
        **_Q4,
    )


def build(learner: str) -> list[Question]:
    """The questions of lesson 04 for one learner, in notebook order.

    Parameters
    ----------
    learner : str
        The learner's id; it seeds every question's numbers (``""``: the class's shared variant).

    Returns
    -------
    list of Question
        q1, q2, q3, q4, with their answer keys.
    """
    return [_q1(learner), _q2(learner), _q3(learner), _q4(learner)]
