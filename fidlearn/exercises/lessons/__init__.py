"""The lessons, one module each, registered here in notebook order.

A lesson module holds ``NUMBER``, ``TOPIC``, ``TITLE``, ``INTRO`` and ``build(learner)``, which
returns the lesson's questions in the order the notebook asks them. Each question ``qN`` has its
words in ``_QN`` (title, task, hint, solution code, level) and one builder ``_qN(learner)`` that
draws the learner's numbers from ``_rng(NUMBER, learner, "qN")``, computes the key and the
mistakes it recognises, and returns the :class:`~fidlearn.exercises.Question`. To add a question,
write both and list the builder in ``build``; to add a lesson, write ``lNN_topic.py`` on that
model and add it to :data:`MODULES`. Then rebuild the exercise notebooks with
``tools/make_student_copies.py``.
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
    l10_tracking,
    l11_mapping,
    l12_own_camera,
    l13_hand_eye,
    l14_charuco,
    l15_wide_lenses,
)

__all__ = ["MODULES"]

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
    l10_tracking,
    l11_mapping,
    l12_own_camera,
    l13_hand_eye,
    l14_charuco,
    l15_wide_lenses,
)

for _module in MODULES:
    _register(_module.NUMBER, _module.TOPIC, _module.TITLE, _module.INTRO, _module.build)
del _module, _register
