"""Outputs staged in hidden files beside their names and renamed together, safe from signals.

One command's outputs (a camera file, its report, its annotated pictures) appear all together
or not at all: :class:`StagedOutputs` writes each to a hidden temporary file in its folder and
renames them at the end with SIGINT, SIGTERM and SIGHUP deferred (:func:`signals_deferred`),
so an interruption at any moment finds every output written or none, and no temporary file. A
rename that fails (a full disk, a folder made read-only) puts back the files renamed before it:
each earlier file as it was, byte for byte with its mode, and no new file where there was none.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import stat
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path

from .errors import FidlearnError


def file_mode_for(path: str | os.PathLike) -> int:
    """The permission bits a file written at ``path`` should get.

    An existing file keeps its own; a new one gets what ``open()`` would give it
    (``0o666`` less the umask). Temporary files from :func:`tempfile.mkstemp` are
    private (``0o600``): renamed into place unchanged, they would leave outputs
    that nobody else (a web server, a teammate, a robot's service user) can read.

    Parameters
    ----------
    path : str or os.PathLike
        The file about to be written (it may not exist yet).

    Returns
    -------
    int
        Permission bits, e.g. ``0o644``.
    """
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


# -- outputs staged beside their names and committed together -------------------------------------
_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))
_local = threading.local()


@contextlib.contextmanager
def signals_deferred():
    """SIGINT, SIGTERM and SIGHUP wait until the block is done, then act as they would have.

    Python runs its signal handlers in the main thread between two steps of the program; in this
    block they only note the signal, and the first one noted is handed to its own handler when
    the block ends (``KeyboardInterrupt`` for Ctrl-C). Another thread is never interrupted by a
    handler, so there the block changes nothing.

    Yields
    ------
    None
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    old: dict = {}
    try:
        for sig in _SIGNALS:
            if signal.getsignal(sig) is not None:  # None: set outside Python, cannot be put back
                old[sig] = signal.signal(sig, lambda signum, _frame: caught.append(signum))
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
    if caught:
        handler = old[caught[0]]
        if callable(handler):
            handler(caught[0], None)
        elif handler == signal.SIG_DFL:
            signal.raise_signal(caught[0])


#: Test-only: ``KIND:N:SIGNAME`` (e.g. ``renamed:1:SIGTERM``) sends SIGNAME to this process at the N-th
#: point of that kind ("staged": an output written whole; "renamed": one renamed in a commit; "committed":
#: a commit done), so that a test can interrupt the real commit at exactly that step.
SIGNAL_AT_VARIABLE = "FIDLEARN_TEST_SIGNAL_AT"
_points: dict[str, int] = {}


def _signal_point(kind: str) -> None:
    spec = os.environ.get(SIGNAL_AT_VARIABLE, "").split(":")
    if len(spec) != 3 or spec[0] != kind or not spec[1].isdigit() or not hasattr(signal, spec[2]):
        return
    _points[kind] = _points.get(kind, 0) + 1
    if _points[kind] == int(spec[1]):
        signal.raise_signal(getattr(signal, spec[2]))


def _hidden_prefix(name: str) -> str:
    """``.NAME.`` with at most 80 bytes of ``name``: a hidden name within the 255 bytes a name may have."""
    return "." + name.encode("utf-8", "replace")[:80].decode("utf-8", "ignore") + "."


class _Entry:
    """One output: its hidden temporary file, its name, whether it is whole, the folder it belongs to."""

    __slots__ = ("tmp", "path", "whole", "group")

    def __init__(self, tmp: Path, path: Path, group: Path | None):
        self.tmp, self.path, self.whole, self.group = tmp, path, False, group


def _folder_of(path: Path) -> Path:
    return path.parent if str(path.parent) else Path(".")


def _check_destination(path: Path, made_at_commit: bool) -> None:
    folder = _folder_of(path)
    if not made_at_commit and not folder.is_dir():
        raise FidlearnError(f"{path}: the folder {folder} does not exist; create it first")
    if path.is_dir():
        raise FidlearnError(f"{path}: is a folder; give the name of the file to write (a path inside it)")
    if path.exists() and not path.is_file():  # a device, a FIFO, a socket: the rename would put a file in its place
        kind = (
            "a FIFO" if path.is_fifo() else "a device" if path.is_char_device() or path.is_block_device() else "no file"
        )
        raise FidlearnError(
            f"{path}: is {kind}, not a file; fidlearn writes a whole file and renames it into place, which would "
            "replace it: give the name of a file to write"
        )


class StagedOutputs:
    """The outputs of one piece of work, each staged in a hidden file beside its name, renamed together.

    While it is active (``with StagedOutputs() as outputs:``) every :func:`atomic_write` in the
    thread stages its file here instead of renaming it at once. :meth:`commit` renames every whole
    staged file with SIGINT, SIGTERM and SIGHUP deferred, so a signal finds all of them renamed or
    none, and a rename that fails puts back those renamed before it; leaving the block with an
    error (or an interruption, unless ``keep_on_interrupt``) removes every staged file.
    :attr:`committed` says exactly what was written.

    Parameters
    ----------
    keep_on_interrupt : bool
        Commit the whole staged files when the block is left by ``KeyboardInterrupt`` (SIGINT,
        or SIGTERM as the command line handles it), as ``fidlearn locate`` keeps finished frames.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     with StagedOutputs() as outputs:
    ...         _ = outputs.stage(Path(folder) / "a.txt", lambda tmp: tmp.write_text("a"))
    ...         _ = outputs.stage(Path(folder) / "b.txt", lambda tmp: tmp.write_text("b"))
    ...         before = sorted(p.name for p in Path(folder).iterdir() if not p.name.startswith("."))
    ...     before, sorted(p.name for p in Path(folder).iterdir()), len(outputs.committed)
    ([], ['a.txt', 'b.txt'], 2)
    """

    def __init__(self, keep_on_interrupt: bool = False):
        self.keep_on_interrupt = keep_on_interrupt
        self.staged: list[_Entry] = []
        self.committed: list[_Entry] = []
        self.folders: list[Path] = []

    def __enter__(self) -> StagedOutputs:
        _stack().append(self)
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        stack = _stack()
        if self in stack:
            stack.remove(self)
        if exc_type is None or (self.keep_on_interrupt and issubclass(exc_type, KeyboardInterrupt)):
            self.commit()
        else:
            self.discard()

    def staging_folder(self, name: Path) -> Path:
        """A hidden folder beside ``name`` for temporary files, removed at the end.

        Parameters
        ----------
        name : Path
            The folder the outputs will go to (it may not exist yet).

        Returns
        -------
        Path
            The hidden folder.
        """
        with signals_deferred():
            tmp = Path(tempfile.mkdtemp(prefix=_hidden_prefix(Path(name).name), dir=_folder_of(Path(name))))
            self.folders.append(tmp)
        return tmp

    def temp(self, path: str | os.PathLike, folder: Path | None = None, group: Path | None = None) -> _Entry:
        """Register a new empty hidden file that will become ``path`` (created in ``folder`` if given).

        Parameters
        ----------
        path : str or os.PathLike
            The output's name.
        folder : Path, optional
            Where the hidden file goes (default: beside ``path``); ``path``'s folder is then made at commit.
        group : Path, optional
            The folder of outputs this one is counted in (``--annotate DIR``).

        Returns
        -------
        _Entry
            ``tmp`` to write to; set ``whole`` once it is complete.
        """
        path = Path(path)
        _check_destination(path, folder is not None)
        where = folder if folder is not None else _folder_of(path)
        try:
            with signals_deferred():
                # the hidden name within the 255 bytes a name may have, however long the user's
                fd, name = tempfile.mkstemp(
                    prefix=_hidden_prefix(path.name), suffix=path.suffix[:20] or ".tmp", dir=where
                )
                os.close(fd)
                entry = _Entry(Path(name), path, group)
                self.staged.append(entry)
        except OSError as exc:
            raise FidlearnError(
                f"{path}: cannot write in {where} ({exc.strerror or exc}); check the folder's permissions; "
                f"{self.written()}"
            ) from None
        return entry

    def stage(self, path: str | os.PathLike, write: Callable[[Path], object], **where) -> Path:
        """Write an output to its hidden file now; it takes its name at :meth:`commit`.

        Parameters
        ----------
        path : str or os.PathLike
            The output's name.
        write : callable(Path)
            Writes the whole content to the path it receives.
        **where
            ``folder`` and ``group``, as :meth:`temp` takes them.

        Returns
        -------
        Path
            ``path``.

        Raises
        ------
        FidlearnError
            The folder does not exist, ``path`` is a folder, or the disk refused (full, no permission);
            the message says what was written before (nothing, unless committed earlier).
        """
        entry = self.temp(path, **where)
        try:
            write(entry.tmp)
            os.chmod(entry.tmp, file_mode_for(entry.path))
        except OSError as exc:  # disk full, permission denied, ...: name the user's file, never the hidden one
            self._drop([entry])
            raise FidlearnError(
                f"{entry.path}: cannot write it ({exc.strerror or exc}); check the free disk space and the "
                f"folder's permissions; {self.written()}"
            ) from None
        except BaseException:
            self._drop([entry])
            raise
        entry.whole = True
        _signal_point("staged")
        return entry.path

    def commit(self, entries: list[_Entry] | None = None) -> list[Path]:
        """Rename the whole staged files (all, or ``entries``) to their names, signals deferred, all or none.

        Each file that a name already holds is first kept under a hidden name beside it; if a rename
        fails, the files this call renamed before it are put back as they were (or removed where
        there was none), and every staged file is removed.

        Parameters
        ----------
        entries : list, optional
            Only these (a stream that keeps its records on an interruption); default every staged file.

        Returns
        -------
        list of Path
            The files written by this call.

        Raises
        ------
        FidlearnError
            A rename failed; nothing of this call was written, and the message says what earlier
            commits wrote.
        """
        batch = [e for e in self.staged if e.whole and (entries is None or e in entries)]
        steps: list[_Step] = []
        made: list[Path] = []
        with signals_deferred():
            try:
                for entry in batch:
                    _rename_into_place(entry, steps, made)
                    _signal_point("renamed")
            except OSError as exc:
                raise self._refused(entry.path, exc, self._roll_back(steps, made)) from None
            except BaseException:
                self._roll_back(steps, made)
                raise
            for step in steps:
                step.forget()
            done = set(batch)
            self.staged = [e for e in self.staged if e not in done]
            self.committed += batch
            if entries is None:
                self.discard()
            _signal_point("committed")
        return [e.path for e in batch]

    def _roll_back(self, steps: list[_Step], made: list[Path]) -> list[str]:
        """Undo ``steps`` (the last first), remove the folders made and every staged file; say what stays."""
        problems = []
        for step in reversed(steps):
            problem = step.put_back()
            if problem:
                problems.append(problem)
                if step.replaced:  # the new output stays: it is written
                    self.committed.append(step.entry)
        for folder in reversed(made):
            with contextlib.suppress(OSError):
                folder.rmdir()
        self.discard()
        return problems

    def _refused(self, path: Path, exc: OSError, problems: list[str]) -> FidlearnError:
        """A failed commit's error: the user's file, what to check, and that nothing more was written."""
        said = [
            f"{path}: cannot write it ({exc.strerror or exc})",
            "check the free disk space and the folder's permissions",
        ]
        said += problems or (["nothing more was written"] if self.committed else [])
        return FidlearnError("; ".join([*said, self.written()]))

    def discard(self) -> None:
        """Remove every staged file and staging folder (what is committed stays)."""
        self._drop(list(self.staged))
        with signals_deferred():
            for folder in self.folders:
                shutil.rmtree(folder, ignore_errors=True)
            self.folders = []

    def _drop(self, entries: list[_Entry]) -> None:
        with signals_deferred():
            for entry in entries:
                entry.tmp.unlink(missing_ok=True)
                if entry in self.staged:
                    self.staged.remove(entry)

    def written(self) -> str:
        """What is written so far, in words: ``"nothing was written"`` or ``"written: a.json, 3 ... in seen/"``.

        Returns
        -------
        str
            For the closing line of an interrupted or failed command.
        """
        if not self.committed:
            return "nothing was written"
        parts = [str(e.path) for e in self.committed if e.group is None]
        groups: dict[Path, int] = {}
        for e in self.committed:
            if e.group is not None:
                groups[e.group] = groups.get(e.group, 0) + 1
        parts += [f"{n} annotated picture{'s' if n != 1 else ''} in {g}/" for g, n in groups.items()]
        return "written: " + ", ".join(parts)


class _Step:
    """One rename of a commit: the output, its name's previous file kept aside, and what is done so far."""

    __slots__ = ("entry", "backup", "moved", "replaced")

    def __init__(self, entry: _Entry, backup: Path | None, moved: bool):
        self.entry, self.backup, self.moved, self.replaced = entry, backup, moved, False

    def put_back(self) -> str | None:
        """Give the name its previous file again (or none, if it had none); say what failed, if anything."""
        path = self.entry.path
        try:
            if not (self.moved or self.replaced):  # the name still holds its previous file
                self.forget()
            elif self.backup is not None:
                os.replace(self.backup, path)
            else:
                path.unlink(missing_ok=True)
        except OSError as exc:
            kept = f": its previous version is kept as {self.backup}" if self.backup is not None else ""
            return f"{path} could not be put back as it was ({exc.strerror or exc}){kept}"
        return None

    def forget(self) -> None:
        """Remove the previous file kept aside (the commit is done, or the name still holds it)."""
        if self.backup is not None:
            with contextlib.suppress(OSError):
                self.backup.unlink(missing_ok=True)


def _set_aside(path: Path) -> tuple[Path | None, bool]:
    """Keep the file at ``path`` (if any) under a hidden name beside it, to put back if the commit fails.

    Returns
    -------
    tuple
        The hidden name (None when ``path`` holds nothing), and whether ``path`` no longer holds the
        file: a hard link leaves it in place, a rename (where the disk has no hard links) does not.
    """
    if not os.path.lexists(path):  # lexists: a dangling symbolic link is put back too
        return None, False
    fd, name = tempfile.mkstemp(prefix=_hidden_prefix(path.name), suffix=".old", dir=_folder_of(path))
    os.close(fd)
    backup = Path(name)
    try:
        try:
            backup.unlink()
            os.link(path, backup, follow_symlinks=False)  # a symbolic link is kept as itself
            return backup, False
        except (OSError, NotImplementedError):  # no hard links here (FAT, some network shares)
            os.replace(path, backup)
            return backup, True
    except BaseException:
        backup.unlink(missing_ok=True)
        raise


def _rename_into_place(entry: _Entry, steps: list[_Step], made: list[Path]) -> None:
    """Rename ``entry``'s hidden file to its name, noting in ``steps`` (and ``made``) how to undo it."""
    if entry.group is not None and not entry.path.parent.is_dir():
        entry.path.parent.mkdir()
        made.append(entry.path.parent)
    step = _Step(entry, *_set_aside(entry.path))
    steps.append(step)
    os.replace(entry.tmp, entry.path)
    step.replaced = True


def _stack() -> list[StagedOutputs]:
    if not hasattr(_local, "stack"):
        _local.stack = []
    return _local.stack


def current_outputs() -> StagedOutputs | None:
    """The :class:`StagedOutputs` active in this thread, if any.

    Returns
    -------
    StagedOutputs or None
        The innermost one.
    """
    stack = _stack()
    return stack[-1] if stack else None


@contextlib.contextmanager
def outputs_together():
    """The active :class:`StagedOutputs`, or a new one committed when the block ends well.

    Yields
    ------
    StagedOutputs
        Where to stage the files that must appear together.
    """
    current = current_outputs()
    if current is not None:
        yield current
        return
    with StagedOutputs() as outputs:
        yield outputs
