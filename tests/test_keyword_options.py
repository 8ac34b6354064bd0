"""Options are keyword-only: no public callable of fidlearn takes more than four positional arguments.

``plot_scene(m, poses, cam, None, ax, 150, 300, "t", True)`` cannot be read without the signature
beside it, and a parameter added in the middle silently shifts every later argument. So every
public callable takes its essential inputs positionally, in the house order (image or detections,
map, camera, then a pose, or the Axes first for a drawing), and its options after a bare ``*``.

The bound is four positional parameters (``self`` and ``cls`` not counted). Four is what the
essential inputs of nearly every function need: ``estimate_pose(detections, marker_map, camera)``,
``render_scene(marker_map, camera, T_world_camera)``, ``plotting.draw_projected_markers(ax,
marker_map, camera, T_world_camera)``, ``intrinsics_view_polylines(fx, fy, cx, cy)``. A callable
whose essential inputs are more than four (``draw_pose(image, detections, marker_map, camera,
pose)``, ``refine_pose_lm(points_world, points_px, camera, rvec, tvec)`` as
``cv2.solvePnPRefineLM`` takes them) may take all of them positionally, but nothing with a default
(an option) beyond the fourth. A dataclass's generated constructor is not counted: its fields are
the record's contents, in the order its ``Attributes`` list them, not options.

Public means: named in the ``__all__`` of a module of the ``fidlearn`` package whose dotted path has
no part that starts with ``_`` (or, without ``__all__``, a name that does not start with ``_``
defined there), wherever it is defined inside fidlearn, and the public methods of public classes.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil

import fidlearn

MAX_POSITIONAL = 4
SKIP_MODULES = {"fidlearn.__main__"}


def _public_modules():
    names = ["fidlearn"]
    for info in pkgutil.walk_packages(fidlearn.__path__, "fidlearn."):
        if not any(part.startswith("_") for part in info.name.split(".")[1:]) and info.name not in SKIP_MODULES:
            names.append(info.name)
    return [importlib.import_module(n) for n in sorted(names)]


def _public_names(module) -> list[str]:
    if hasattr(module, "__all__"):
        return list(module.__all__)
    return [
        n
        for n, obj in vars(module).items()
        if not n.startswith("_") and getattr(obj, "__module__", "") == module.__name__
    ]


def _callables():
    """(name, callable) for every public function, constructor and method, each once."""
    seen = set()
    for module in _public_modules():
        for name in _public_names(module):
            obj = getattr(module, name, None)
            if not str(getattr(obj, "__module__", "")).startswith("fidlearn") or id(obj) in seen:
                continue
            seen.add(id(obj))
            if inspect.isfunction(obj):
                yield f"{module.__name__}.{name}", obj
            elif inspect.isclass(obj) and not issubclass(obj, BaseException):
                if not dataclasses.is_dataclass(obj) and "__init__" in vars(obj):
                    yield f"{module.__name__}.{name}", obj.__init__
                for attr, member in vars(obj).items():
                    member = member.__func__ if isinstance(member, (staticmethod, classmethod)) else member
                    if not attr.startswith("_") and inspect.isfunction(member):
                        yield f"{module.__name__}.{name}.{attr}", member


def _too_many_positional(fn) -> str:
    """Why ``fn`` breaks the rule, or ``""``."""
    params = [
        p
        for p in inspect.signature(fn).parameters.values()
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) and p.name not in ("self", "cls")
    ]
    options = [p.name for p in params[MAX_POSITIONAL:] if p.default is not p.empty]
    if options:
        return f"{len(params)} positional parameters; make {', '.join(options)} keyword-only (a * before them)"
    return ""


CALLABLES = dict(_callables())


def test_the_walk_reaches_the_functions_re_exported_from_private_modules():
    from fidlearn import calibration, plotting
    from fidlearn.markermap import MarkerMap

    found = set(map(id, CALLABLES.values()))
    for fn in (plotting.plot_scene, calibration.calibrate_charuco, fidlearn.estimate_pose, MarkerMap.__init__):
        assert id(fn) in found
    assert id(fidlearn.Pose.__init__) not in found  # a dataclass's fields


def test_the_rule_knows_an_option_from_an_input():
    def options_positional(ax, marker_map, camera, T_world_camera, color="r", label=None):
        """Two options after four inputs."""

    def inputs_positional(image, detections, marker_map, camera, pose, *, color="r"):
        """Five essential inputs, the options keyword-only."""

    def method(self, a, b, c, d=1):
        """Four after self."""

    assert "make color, label keyword-only" in _too_many_positional(options_positional)
    assert _too_many_positional(inputs_positional) == ""
    assert _too_many_positional(method) == ""


def test_no_public_callable_takes_an_option_beyond_the_fourth_positional_parameter():
    bad = {name: why for name, fn in CALLABLES.items() if (why := _too_many_positional(fn))}
    assert not bad, "\n".join(f"{name}: {why}" for name, why in sorted(bad.items()))
