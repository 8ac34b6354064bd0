"""Write ``tests/data/pose_reference.json``: estimate_pose's answers on the bundled scenes, kept as a reference.

    .venv/bin/python tools/make_pose_reference.py [--out PATH]

The inputs are the true corners of ``data/scenes/poses.json`` (the 10 bundled scenes, on
``world_map.json`` and ``two_walls_map.json``, camera ``data/scenes/camera.json``) with seeded
Gaussian noise, in several variants per scene: every visible marker, the first one alone, the
first two, the true corners without noise, and (with three or more markers) one marker drawn
40 mm from where the map has it. Each variant runs with the noise estimated and given
(``corner_sigma_px``). The file stores the corners it fed in, so the reference does not depend
on the random generator, and per case the pose, the flag, the alternative, the covariance and
the rejected markers, with the commit and versions that computed them.

``tests/test_pose_reference.py`` runs estimate_pose on the stored corners and compares: the
reference is what the code computed when the file was written (see ``provenance``); a change
of these numbers is a change of the method, to be made on purpose and written here anew.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import platform
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

import fidlearn
from fidlearn import Camera, MarkerMap, estimate_pose
from fidlearn.data import data_path, repo_dir
from fidlearn.detection import Detection

OUT = repo_dir() / "tests" / "data" / "pose_reference.json"
SIGMA_PX = 0.5
MOVED_MM = 40.0
SEED = 20261125


def _variants(ids: list[int]) -> list[tuple[str, list[int]]]:
    out = [("all", ids), ("one", ids[:1])]
    if len(ids) >= 3:
        out.append(("two", ids[:2]))
    return out


def _pose_record(pose) -> dict:
    rec = {
        "T_world_camera": pose.T_world_camera.tolist(),
        "marker_ids": list(pose.marker_ids),
        "rejected_ids": list(pose.rejected_ids),
        "ambiguous": bool(pose.ambiguous),
        "reprojection_rms_px": pose.reprojection_rms_px,
        "sigma_px": pose.corner_sigma_px,
        "covariance": None if pose.covariance is None else pose.covariance.tolist(),
        "method": pose.method,
    }
    alt = pose.alternative
    rec["alternative"] = None
    if alt is not None:
        rec["alternative"] = {
            "T_world_camera": alt.T_world_camera.tolist(),
            "covariance": None if alt.covariance is None else alt.covariance.tolist(),
            "method": alt.method,
        }
    return rec


def cases() -> list[dict]:
    """The inputs: per scene and variant, the corners (px) by id, the map file and the noise option."""
    scenes = json.loads(data_path("scenes", "poses.json").read_text())
    camera = Camera.load(data_path("scenes", "camera.json"))
    rng = np.random.default_rng(SEED)
    out = []
    for rec in scenes["images"]:
        m = MarkerMap.load(data_path(rec["map"]))
        true = {int(i): np.asarray(c, dtype=float) for i, c in rec["corners_px"].items()}
        ids = sorted(true)
        noisy = {i: c + rng.normal(0.0, SIGMA_PX, c.shape) for i, c in true.items()}
        inputs = [(f"{name}", {i: noisy[i] for i in sub}) for name, sub in _variants(ids)]
        inputs.append(("exact", {i: true[i] for i in ids}))
        if len(ids) >= 3:
            moved = dict(noisy)
            k = ids[len(ids) // 2]
            corners_w = m.corners()[k] + np.array([0.0, MOVED_MM, 0.0]) * (1 if k % 2 else -1)
            T = np.asarray(rec["T_world_camera"], dtype=float)
            moved[k] = camera.project(corners_w, T) + rng.normal(0.0, SIGMA_PX, (4, 2))
            inputs.append((f"moved_{k}", moved))
        for name, corners in inputs:
            for sigma in (None, SIGMA_PX):
                out.append(
                    {
                        "scene": rec["image"],
                        "map": rec["map"],
                        "variant": name,
                        "corner_sigma_px": sigma,
                        "corners_px": {str(i): c.tolist() for i, c in corners.items()},
                    }
                )
    return out


def run(case: dict) -> dict:
    """estimate_pose on one case's corners."""
    m = MarkerMap.load(data_path(case["map"]))
    camera = Camera.load(data_path("scenes", "camera.json"))
    dets = [Detection(int(i), np.asarray(c)) for i, c in case["corners_px"].items()]
    return _pose_record(estimate_pose(dets, m, camera, corner_sigma_px=case["corner_sigma_px"]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    commit = subprocess.run(
        ["git", "rev-parse", "HEAD"], capture_output=True, text=True, cwd=repo_dir(), check=False
    ).stdout.strip()
    dirty = subprocess.run(
        ["git", "status", "--porcelain", "--", "fidlearn"], capture_output=True, text=True, cwd=repo_dir(), check=False
    ).stdout.strip()
    all_cases = cases()
    for case in all_cases:
        case["expected"] = run(case)
    doc = {
        "what": "estimate_pose(detections, map, camera, corner_sigma_px=...) on the bundled scenes' true corners "
        f"(data/scenes/poses.json) with Gaussian noise of {SIGMA_PX} px (seed {SEED}); a marker moved "
        f"{MOVED_MM} mm along world y in the 'moved_ID' variants",
        "provenance": {
            "script": "tools/make_pose_reference.py",
            "commit": commit + (" with uncommitted changes in fidlearn/" if dirty else ""),
            "date_utc": dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M"),
            "fidlearn": fidlearn.__version__,
            "opencv": cv2.__version__,
            "numpy": np.__version__,
            "python": platform.python_version(),
        },
        "cases": all_cases,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    head = json.dumps({k: v for k, v in doc.items() if k != "cases"}, indent=1)[:-2]
    body = ",\n".join(json.dumps(c, separators=(",", ":")) for c in all_cases)
    args.out.write_text(head + ',\n "cases": [\n' + body + "\n ]\n}\n")  # one case a line
    print(f"wrote {len(all_cases)} cases to {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
