"""A surveyed map against the map it started from (an official field layout): how far each tag moved.

A field's official layout (WPILib's AprilTag JSON) says where each tag should be; the tags on a real field are
within the builders' tolerance of it, and one knocked loose can be a hand's width off. :func:`tag_changes`
compares each surveyed tag with the layout's: the distance between the centres (mm) and the angle between
the faces (deg), each with the survey's own standard deviation (from the placement's covariance, the centre's
moved from the top-left corner's through the rotation), and the survey's suspect test (where the photos alone
put the tag, against the layout's placement with the tolerance learnt from all tags): a tag is *moved* when
that test names it (a :attr:`Survey.suspects` entry), noise otherwise.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..frames import rotation_angle_deg

__all__ = ["TagChange", "tag_changes"]


class TagChange(NamedTuple):
    """One tag of a surveyed map against the map the survey started from (an official layout).

    Attributes
    ----------
    id : int
        The tag.
    offset_mm : ndarray, shape (3,)
        The surveyed centre minus the layout's, world axes, mm.
    distance_mm : float
        Its length: how far the surveyed centre is from the layout's.
    distance_std_mm : float
        The survey's standard deviation of the tag's centre (the length of its three, world axes), mm.
    angle_deg : float
        The angle between the surveyed tag's frame and the layout's, degrees.
    angle_std_deg : float
        The survey's standard deviation of the tag's rotation (the length of its three), degrees.
    sigmas : float
        The survey's suspect test: where the photos alone put the tag's top-left corner against the layout's,
        in standard deviations (photos' and layout tolerance's together); NaN for a tag not tested (in fewer
        than two photos, or held fixed).
    moved : bool
        Whether the test names the tag (one of :attr:`Survey.suspects`): moved beyond the noise.
    photos : int
        Photos that show the tag (0: the layout's placement, nothing measured).
    """

    id: int
    offset_mm: np.ndarray
    distance_mm: float
    distance_std_mm: float
    angle_deg: float
    angle_std_deg: float
    sigmas: float
    moved: bool
    photos: int


def tag_changes(s: Any) -> list[TagChange]:
    """Every tag of the map the survey started from that the surveyed map holds, against its placement there.

    Parameters
    ----------
    s : Survey
        A survey's result.

    Returns
    -------
    list of TagChange
        In the surveyed map's order; the moved tags are those with ``moved``.
    """
    out = []
    suspects = set(s.suspect_ids)
    for i in s.marker_map.placements:
        if i not in s.tape_map:
            continue
        before, after = s.tape_map.T_world_marker(i), s.marker_map.T_world_marker(i)
        offset = after[:3, 3] - before[:3, 3]
        cov = np.asarray(s.marker_covariance.get(i, np.zeros((6, 6))), dtype=np.float64)
        # the centre is the top-left corner plus R v: a small rotation w (world axes) moves it by w x (R v)
        lever = after[:3, 3] - np.asarray(s.marker_map.placements[i].translation_mm, dtype=np.float64)
        J = np.hstack([-_skew(lever), np.eye(3)])
        centre_cov = J @ cov @ J.T if np.all(np.isfinite(cov)) else np.diag([np.inf] * 3)  # unknown: inf, not NaN
        tested = s.tests.get(i)
        out.append(
            TagChange(
                id=i,
                offset_mm=offset,
                distance_mm=float(np.linalg.norm(offset)),
                distance_std_mm=float(np.sqrt(max(np.trace(centre_cov), 0.0))),
                angle_deg=float(rotation_angle_deg(after[:3, :3], before[:3, :3])),
                angle_std_deg=float(np.degrees(np.sqrt(max(np.trace(cov[:3, :3]), 0.0)))),
                sigmas=float(tested[1]) if tested is not None else float("nan"),
                moved=i in suspects,
                photos=int(s.photos_per_marker.get(i, 0)),
            )
        )
    return out


def tag_changes_text(changes: list[TagChange], layout: str = "the official layout") -> list[str]:
    """The lines ``fidlearn survey`` prints for :func:`tag_changes`: a table, then which tags moved.

    Parameters
    ----------
    changes : list of TagChange
        From :func:`tag_changes`.
    layout : str
        What the survey started from, for the lines' wording.

    Returns
    -------
    list of str
        A title, a header, one line per tag and a last line naming the moved tags (or saying none moved).
    """
    lines = [
        f"against {layout} (tag centres; +/- the survey's standard deviation; sigmas: the photos alone against "
        "the layout, its tolerance learnt from every tag):",
        f"{'tag':>4} {'moved (mm)':>16} {'dx, dy, dz (mm)':>20} {'turned (deg)':>14} {'sigmas':>7}  verdict",
    ]
    for c in changes:
        sig = f"{c.sigmas:7.1f}" if c.sigmas == c.sigmas else f"{'-':>7}"
        if c.photos == 0:
            verdict = "in no photo: not measured"
        elif c.moved:
            verdict = "MOVED: put the tag back, or use the surveyed layout"
        else:
            verdict = "within the noise"
        lines.append(
            f"{c.id:>4} {c.distance_mm:7.1f} +/- {c.distance_std_mm:4.1f} "
            f"{', '.join(f'{v:+.0f}' for v in c.offset_mm):>20} {c.angle_deg:6.2f} +/- {c.angle_std_deg:4.2f} "
            f"{sig}  {verdict}"
        )
    moved = [c.id for c in changes if c.moved]
    lines.append(
        f"tags moved from {layout}: {', '.join(str(i) for i in moved)}"
        if moved
        else f"no tag moved from {layout} beyond what the survey's noise and the layout's tolerance explain"
    )
    return lines


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
