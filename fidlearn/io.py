r"""Reading a user's files safely and writing outputs that appear whole or not at all.

Everything fidlearn itself reads and writes goes through these, and so do the ``fidlearn``
command and the repository's scripts:

* :func:`read_bytes` reads a regular file of bounded size (a FIFO, a device, a folder is refused
  before it is opened, a file over the limit before it is read); :func:`read_json` reads JSON
  strictly (duplicate keys, ``NaN``, syntax errors raise with the file's name);
  :func:`image_size_from_header` gives a picture's size from its header, no pixel decoded.
* :func:`atomic_write`, :func:`write_text_atomic` and :func:`write_json_atomic` write to a hidden
  temporary file beside the target and rename it: a reader never sees half a file.
* :class:`StagedOutputs` stages a command's several outputs and renames them together at its end,
  with SIGINT, SIGTERM and SIGHUP deferred (:func:`signals_deferred`); :func:`current_outputs` is
  the one active in this thread, :func:`outputs_together` the active one or a new one.

Examples
--------
>>> import tempfile, pathlib
>>> with tempfile.TemporaryDirectory() as folder:
...     write_text_atomic(pathlib.Path(folder) / "note.txt", "hello\n").read_text()
'hello\n'
>>> image_size_from_header(b"GIF89a" + bytes([64, 0, 48, 0]))
('GIF', 64, 48)
"""

from __future__ import annotations

from ._files import MAX_IMAGE_BYTES, MAX_IMAGE_PIXELS, MAX_TEXT_BYTES, image_size_from_header, read_bytes
from ._io import atomic_write, read_json, write_json_atomic, write_text_atomic
from ._staged import StagedOutputs, current_outputs, file_mode_for, outputs_together, signals_deferred

__all__ = [
    "MAX_IMAGE_BYTES",
    "MAX_IMAGE_PIXELS",
    "MAX_TEXT_BYTES",
    "StagedOutputs",
    "atomic_write",
    "current_outputs",
    "file_mode_for",
    "image_size_from_header",
    "outputs_together",
    "read_bytes",
    "read_json",
    "signals_deferred",
    "write_json_atomic",
    "write_text_atomic",
]
