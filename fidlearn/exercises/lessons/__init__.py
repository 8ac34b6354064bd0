"""The nine lessons, one module each, registered here in notebook order.

A lesson module holds ``NUMBER``, ``TOPIC``, ``TITLE``, ``INTRO`` and ``build(learner)``, which
returns the lesson's questions in the order the notebook asks them (one private builder per
question, ``_q1``, ``_q2``...). To add a lesson, write ``lNN_topic.py`` on that model and add it
to :data:`MODULES`.
"""

from __future__ import annotations

from .._registry import _register
from . import (
    l01_pinhole,
    l02_calibration,
    l03_extrinsics,
    l04_world_map,
    l05_detection,
    l06_pnp,
    l07_inversion,
    l08_accuracy,
    l09_robot,
)

#: The lesson modules in notebook order.
MODULES = (
    l01_pinhole,
    l02_calibration,
    l03_extrinsics,
    l04_world_map,
    l05_detection,
    l06_pnp,
    l07_inversion,
    l08_accuracy,
    l09_robot,
)

for _module in MODULES:
    _register(_module.NUMBER, _module.TOPIC, _module.TITLE, _module.INTRO, _module.build)
