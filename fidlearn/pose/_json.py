"""A :class:`Pose` as JSON data and back: the record ``fidlearn locate --json`` writes for each frame."""

from __future__ import annotations

import math

import numpy as np

from .. import frames
from .._files import did_you_mean
from .._map_parse import key_from_json, key_json
from ..errors import FidlearnError, PoseError

#: The fields of the record, in the order written; ``alternative_position_mm`` only for a pose with one.
RECORD_FIELDS = (
    "T_world_camera",
    "position_mm",
    "rpy_deg",
    "position_std_mm",
    "marker_ids",
    "reprojection_rms_px",
    "ambiguous",
    "rejected_ids",
    "ignored_ids",
    "method",
    "alternative_position_mm",
)
#: What ``full=True`` adds: everything else a Pose holds.
FULL_FIELDS = ("covariance", "corner_sigma_px", "residuals_px", "alternative")
#: A ``fidlearn locate --json`` line's own fields, read past.
FRAME_FIELDS = ("frame", "located")


def pose_to_dict(pose, full: bool) -> dict:
    """The pose's record (see :meth:`Pose.to_dict`)."""
    rec = {
        "T_world_camera": np.asarray(pose.T_world_camera).tolist(),
        "position_mm": pose.position_mm.tolist(),
        "rpy_deg": pose.rpy_deg.tolist(),
        # null, not NaN, when the pose is not determined: NaN is not JSON (strict readers, fidlearn's own, refuse it)
        "position_std_mm": pose.position_std_mm.tolist() if pose.covariance is not None else None,
        "marker_ids": [key_json(k) for k in pose.marker_ids],
        "reprojection_rms_px": pose.reprojection_rms_px,
        "ambiguous": bool(pose.ambiguous),
        "rejected_ids": [key_json(k) for k in pose.rejected_ids],
        "ignored_ids": [key_json(k) for k in pose.ignored_ids],
        "method": pose.method,
    }
    if pose.alternative is not None:
        rec["alternative_position_mm"] = pose.alternative.position_mm.tolist()
    if full:
        rec["covariance"] = None if pose.covariance is None else np.asarray(pose.covariance).tolist()
        rec["corner_sigma_px"] = float(pose.corner_sigma_px) if math.isfinite(pose.corner_sigma_px) else None
        rec["residuals_px"] = {str(i): np.asarray(r).tolist() for i, r in pose.residuals_px.items()}
        rec["alternative"] = None if pose.alternative is None else pose_to_dict(pose.alternative, True)
    return rec


def _ids(d: dict, key: str, source: str) -> tuple[int, ...]:
    value = d.get(key, [])
    keys = [key_from_json(i) for i in value] if isinstance(value, list) else [None]
    if any(k is None for k in keys):
        raise PoseError(
            f'{source}: {key} must be a list of marker ids (whole numbers >= 0, or "4X4_50:3" for a marker of '
            f"another dictionary than the map's), got {value!r:.60}"
        )
    return tuple(k for k in keys if k is not None)


def _number(value, key: str, source: str, allow_none: bool = False) -> float:
    if value is None and allow_none:
        return math.nan
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise PoseError(f"{source}: {key} must be a non-negative number of pixels, got {value!r:.60}")
    return float(value)


def _covariance(value, source: str) -> np.ndarray | None:
    if value is None:
        return None
    try:
        cov = np.array(value, dtype=float)
    except (TypeError, ValueError):
        cov = np.zeros(0)
    if cov.shape != (6, 6) or not np.isfinite(cov).all() or not np.allclose(cov, cov.T, atol=1e-9 * np.abs(cov).max()):
        raise PoseError(f"{source}: covariance must be a symmetric 6x6 list of finite numbers, or null")
    return cov


def _residuals(value, source: str) -> dict[int, np.ndarray]:
    if not isinstance(value, dict):
        raise PoseError(f"{source}: residuals_px must be an object of marker id to 4x2 pixels")
    out = {}
    for key, r in value.items():
        i = key_from_json(int(key) if isinstance(key, str) and key.strip().isdigit() else key)
        try:
            arr = np.array(r, dtype=float)
        except (TypeError, ValueError, OverflowError):
            arr = None
        if i is None or arr is None or arr.shape != (4, 2) or not np.isfinite(arr).all():
            raise PoseError(f"{source}: residuals_px[{key!r}] must be 4x2 pixels (TL, TR, BR, BL) under a marker id")
        out[i] = arr
    return out


def _check_fields(d, source: str) -> None:
    if not isinstance(d, dict):
        raise PoseError(f"{source}: expected a JSON object with T_world_camera, marker_ids, reprojection_rms_px")
    known = RECORD_FIELDS + FULL_FIELDS + FRAME_FIELDS
    for key in d:
        if key not in known:
            raise PoseError(f"{source}: unknown field {key!r}{did_you_mean(key, known)}")
    for key in ("T_world_camera", "marker_ids", "reprojection_rms_px"):
        if key not in d:
            raise PoseError(
                f"{source}: missing field {key} (a record as Pose.to_dict() or 'fidlearn locate --json' writes)"
            )
    if d.get("located", True) is not True:
        raise PoseError(f"{source}: the frame was not located (located: false): it holds no pose to read")


def pose_from_dict(cls, d, source: str):
    """A Pose from its record (see :meth:`Pose.from_dict`)."""
    _check_fields(d, source)
    try:
        T = frames.check_transform(np.array(d["T_world_camera"], dtype=float), "T_world_camera")
    except (TypeError, ValueError, FidlearnError) as exc:
        raise PoseError(f"{source}: T_world_camera must be a 4x4 rigid transform (mm): {exc}") from None
    for key in ("ambiguous",):
        if not isinstance(d.get(key, False), bool):
            raise PoseError(f"{source}: {key} must be true or false, got {d[key]!r:.60}")
    if not isinstance(d.get("method", ""), str):
        raise PoseError(f"{source}: method must be text (the solver, e.g. 'ippe+lm'), got {d['method']!r:.60}")
    alternative = d.get("alternative")
    if alternative is not None:
        alternative = pose_from_dict(cls, alternative, f"{source}: alternative")
    return cls(
        T_world_camera=T,
        marker_ids=_ids(d, "marker_ids", source),
        residuals_px=_residuals(d.get("residuals_px", {}), source),
        reprojection_rms_px=_number(d["reprojection_rms_px"], "reprojection_rms_px", source),
        covariance=_covariance(d.get("covariance"), source),
        corner_sigma_px=_number(d.get("corner_sigma_px"), "corner_sigma_px", source, allow_none=True),
        ambiguous=d.get("ambiguous", False),
        alternative=alternative,
        ignored_ids=_ids(d, "ignored_ids", source),
        rejected_ids=_ids(d, "rejected_ids", source),
        method=d.get("method", ""),
    )
