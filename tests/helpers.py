"""Helpers shared by tests: the command line run in-process, exercises solved, commands run as another user."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import stat
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def python_paths() -> list[Path]:
    """The checkout, the venv and the base interpreter's installation."""
    return [ROOT, Path(sys.prefix), Path(os.path.realpath(sys.executable)).parent, Path(sys.base_prefix)]


def as_unprivileged(uid: int, gid: int, paths: list[Path]) -> list[str] | None:
    """A command prefix (bubblewrap, then setpriv) that runs a program as ``uid`` with ``paths`` reachable.

    The machine's folders keep their modes: in a mount namespace of its own, each folder above
    ``paths`` that others cannot enter (pyenv's /root, mode 700) is replaced by an empty tmpfs
    (mode 755) into which ``paths`` are bound back. None where bubblewrap or setpriv is missing or
    the caller is not root.
    """
    bwrap, setpriv = shutil.which("bwrap"), shutil.which("setpriv")
    if os.geteuid() != 0 or bwrap is None or setpriv is None:
        return None
    closed = set()
    for path in paths:
        for folder in reversed(path.resolve().parents):
            if not folder.stat().st_mode & stat.S_IXOTH:
                closed.add(folder)
                break
    cmd = [bwrap, "--dev-bind", "/", "/", "--die-with-parent"]
    for folder in sorted(closed, key=lambda p: len(p.parts)):
        cmd += ["--perms", "0755", "--tmpfs", str(folder)]
    inside = sorted({p.resolve() for p in paths if any(c in p.resolve().parents for c in closed)})
    above = {a for p in inside for c in closed if c in p.parents for a in p.parents if c in a.parents}
    for folder in sorted(above, key=lambda p: len(p.parts)):  # the folders between, open to others
        cmd += ["--perms", "0755", "--dir", str(folder)]
    for path in inside:
        cmd += ["--ro-bind", str(path), str(path)]
    return [*cmd, setpriv, f"--reuid={uid}", f"--regid={gid}", "--clear-groups", "--"]


@contextlib.contextmanager
def ctrl_c_as_a_terminal_gives_it():
    """SIGINT raising KeyboardInterrupt here, and at its default in the commands started, for the block.

    A test run started in the background by a non-interactive shell (CI, ``make test &``) inherits
    SIGINT ignored, and so would every command a test starts; the tests of Ctrl-C need it as a
    terminal gives it.
    """
    old = signal.getsignal(signal.SIGINT)
    if old == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        if old == signal.SIG_IGN:
            signal.signal(signal.SIGINT, old)


def run_cli(capsys, *argv):
    """Run the ``fidlearn`` command in-process; returns (status, stdout, stderr)."""
    from fidlearn.cli import main

    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_user_error(code, err, *fragments):
    """A user error as the CLI reports it: status 2, one ``error:`` line holding every fragment, no traceback."""
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert "Traceback" not in err, err
    for f in fragments:
        assert f in lines[0], lines[0]


def solved(lesson: str, name: str, learner: str):
    """A lesson's question for a learner and the answer its shown solution computes."""
    from fidlearn import exercises

    q = exercises.lesson(lesson, learner=learner)[name]
    ns: dict = {}
    exec(exercises.SETUP_CODE, ns)
    ns[name] = q
    exec(q.solution_code, ns)
    return q, q.answer


def named(q, answer, words: str) -> None:
    """A wrong answer graded incorrect, with a message naming the mistake (``words``)."""
    from fidlearn.exercises import INCORRECT

    r = q.grade(answer)
    assert r.status == INCORRECT, (answer, r)
    assert words in r.message, r.message


def survey_walk_room(camera, n_photos: int = 20, seed: int = 1, truth=None):
    """``(truth, poses)``: a room (``fidlearn.synthetic.survey_room()`` unless ``truth``) and a walk through it."""
    from fidlearn.synthetic import survey_room, survey_walk

    truth = survey_room() if truth is None else truth
    return truth, survey_walk(truth, camera, n_photos=n_photos, seed=seed)


def projected_photos(truth, camera, poses, noise_px: float = 0.0, seed: int = 0, drop=()) -> list:
    """Each pose's detections: the true corners of the markers it sees whole (each in its dictionary), plus noise.

    Gaussian noise of ``noise_px`` per coordinate (``numpy.random.default_rng(seed)``); the map's keys in
    ``drop`` are left out.
    """
    import numpy as np

    from fidlearn.detection import Detection
    from fidlearn.synthetic import visible_markers

    rng = np.random.default_rng(seed)
    return [
        [
            Detection(int(k), c + rng.normal(0, noise_px, c.shape), truth.marker_dictionary(k))
            for k, c in visible_markers(truth, camera, T).items()
            if k not in drop
        ]
        for T in poses
    ]


def with_placements(m, placements: dict, units: str | None = None):
    """The map ``m`` with other placements (and units)."""
    from fidlearn.markermap import MarkerMap

    return MarkerMap(placements, m.marker_size_mm, dictionary=m.dictionary, units=units or m.units, source=m.source)


def corner_error_mm(a, b, ids=None) -> float:
    """The largest coordinate difference (mm) of the two maps' corners, over ``ids`` (all of ``b``'s)."""
    import numpy as np

    ca, cb = a.corners(), b.corners()
    return max(float(np.abs(ca[i] - cb[i]).max()) for i in ids or b.ids)


def noise_free_survey(truth, poses, camera):
    """The survey of noise-free photos with a rough tape (20 mm, 2 degrees), marker 0 exact and held."""
    import math

    import fidlearn
    from fidlearn.synthetic import tape_measured

    tape = tape_measured(truth, sigma_mm=20.0, sigma_deg=2.0, seed=3)
    tape = with_placements(tape, {**tape.placements, 0: truth.placements[0]})
    return fidlearn.survey(projected_photos(truth, camera, poses), tape, camera, map_sigma_mm=math.inf, fixed_ids=[0])


def small_survey_problem(truth, poses, camera):
    """The survey's problem of 6 photos (0.2 px noise), one marker held, tape priors on all but two markers."""
    from fidlearn.survey._geometry import marker_sizes
    from fidlearn.survey._solve import build_problem
    from fidlearn.survey._survey import _read_photos, initial_values
    from fidlearn.synthetic import tape_measured

    tape = tape_measured(truth, sigma_mm=20.0, sigma_deg=2.0, seed=4)
    ph = _read_photos(projected_photos(truth, camera, poses[:6], 0.2), tape, camera, None)
    placed, _ = initial_values(ph, tape)
    ids = sorted({i for p in ph for i in p.corners})
    opts = {"marker_size_mm": tape.marker_size_mm, "sizes": marker_sizes(tape, ids), "sigma_px": 0.3}
    opts.update(sigma_mm=20.0, sigma_rot_rad=0.1)
    return build_problem(ph, ids[1:] + ids[:1], len(ids) - 1, placed, {i: placed[i] for i in ids[2:]}, opts)


def jacobian_error(prob, seed: int = 1) -> float:
    """The analytic Jacobian's largest difference from central differences, over the largest entry (or 1)."""
    import numpy as np

    x = np.random.default_rng(seed).normal(0, 0.02, prob.n_params)
    J = prob.jacobian(x).toarray()
    num = np.zeros_like(J)
    for k in range(prob.n_params):
        e = np.zeros_like(x)
        e[k] = 1e-6
        num[:, k] = (prob.residuals(x + e) - prob.residuals(x - e)) / 2e-6
    return float(np.abs(J - num).max() / max(1.0, np.abs(num).max()))


def survey_with_marker_7_moved(truth, poses, camera):
    """``(tape, survey)``: marker 7 taped 100 mm off (tape 20 mm, 0.1 px corners), named and put back by the photos."""
    import numpy as np

    import fidlearn
    from fidlearn.synthetic import tape_measured

    tape = tape_measured(truth, sigma_mm=20.0, sigma_deg=1.0, moved={7: (0.0, 100.0, 0.0)}, seed=5)
    s = fidlearn.survey(projected_photos(truth, camera, poses, 0.1), tape, camera, map_sigma_mm=20)
    assert s.suspect_ids[0] == 7, s.suspects
    assert 60 < s.suspects[0].distance_mm < 160
    assert s.suspects[0].sigmas > 3.4
    # where the photos put it: within the map's overall placement (the tape's gauge, ~10 mm) of the truth
    moved = np.subtract(s.marker_map.placements[7].translation_mm, truth.placements[7].translation_mm)
    assert np.linalg.norm(moved) < 40
    return tape, s


def eight_marker_wall():
    """Eight 80 mm markers on the wall X = 0, in two rows (z 300 and 800 mm) of four (y -450 to 450 mm)."""
    from fidlearn import MarkerMap

    places = [(y, z) for y in (-450, -150, 150, 450) for z in (300, 800)]
    markers = {str(k): {"translation": [0, y, z], "rotation": [0, 0, 0]} for k, (y, z) in enumerate(places)}
    return MarkerMap.from_dict({"units": "mm", "marker_size_mm": 80.0, "markers": markers})


def corner_noise_roots(truth: dict, sigma: float, shift: float) -> dict:
    """Per marker, a Cholesky root (8, 8) of the noise model's corner covariance at its corners ``truth[i]``:
    corner noise ``sigma`` and a shift of the whole marker ``shift`` (px per axis)."""
    import numpy as np

    from fidlearn.planning import noise

    return {
        i: np.linalg.cholesky(noise.corner_covariance(c, sigma) + noise.marker_shift_covariance(shift))
        for i, c in truth.items()
    }
