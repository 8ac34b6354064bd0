"""Copy the fisheye checkerboard photos' subset into data/real/fisheye_checkerboard, with every photo's corners.

    .venv/bin/python tools/make_fisheye_corners.py SOURCE

``SOURCE`` holds ``mono/left-*.png`` and ``stereo/left-*.png``, ``stereo/right-*.png`` with ROS's calibrations
``mono/ost.yaml``, ``stereo/left.yaml``, ``stereo/right.yaml`` (ros-perception/image_pipeline, pull request 439,
``camera_calibration_fisheye/fiseye_cal_reference/``). Six photos of each set, evenly spread through it, are
copied unchanged; ``corners.json`` holds the 6 x 8 inner corners of every photo of the three sets as
``fidlearn.calibration.find_checkerboard_corners`` finds them (px, pixel centres at integers), so that a
calibration of each whole set runs without its 20 MB of photos.
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import cv2
import numpy as np

from fidlearn.calibration import find_checkerboard_corners

SETS = {"mono": ("mono", "left-*.png", "ost.yaml"), "left": ("stereo", "left-*.png", "left.yaml"),
        "right": ("stereo", "right-*.png", "right.yaml")}  # fmt: skip
PER_SET = 6
PATTERN = (6, 8)


def main(source: Path) -> None:
    out = Path(__file__).resolve().parents[1] / "data" / "real" / "fisheye_checkerboard"
    corners: dict = {"pattern": list(PATTERN), "opencv": cv2.__version__, "sets": {}}
    for name, (folder, pattern, reference) in SETS.items():
        files = sorted((source / folder).glob(pattern))
        (out / name).mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source / folder / reference, out / name / reference)
        for k in np.linspace(0, len(files) - 1, PER_SET).round().astype(int):
            shutil.copyfile(files[k], out / name / files[k].name)
        found = {}
        for f in files:
            c = find_checkerboard_corners(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE), PATTERN)
            if c is not None:
                found[f.name] = np.round(np.asarray(c, dtype=float).reshape(-1, 2), 4).tolist()
        corners["sets"][name] = found
        print(f"{name}: {len(found)} of {len(files)} photos with corners, {PER_SET} copied")
    (out / "corners.json").write_text(json.dumps(corners, separators=(",", ":")) + "\n")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
