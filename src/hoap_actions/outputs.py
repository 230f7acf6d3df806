"""Exclusive, atomic output files: every writer of datasets, models, reports and videos goes through here.

A long job claims its outputs *before* it starts (so a bad path or an existing file fails in a
second, not after an hour of recording), writes to a hidden partial beside the target, and
publishes it in one atomic step at the end:

- the claim is a partial file ``.<stem>.hoap-partial<suffix>`` (the suffix kept, for writers that
  pick a format from it) or staging folder ``.<what>.hoap-partial``, holding an exclusive
  ``flock``: of two concurrent runs aimed at one target, the second gets :class:`DataExistsError`
  at once; the lock dies with its process, so a killed run never blocks a later one;
- publishing without ``overwrite`` is ``os.link`` (create-or-fail: a file that appeared meanwhile
  is never replaced); with ``overwrite`` it is ``os.replace``;
- a failed or interrupted job removes its partial; partials left by killed processes (their locks
  are free) are swept by the next claim in the same folder.

POSIX only for the lock (``fcntl``); elsewhere the claim falls back to create-or-fail without
stale-partial detection.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import shutil
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from hoap_actions.errors import DataExistsError, InvalidInputError, OutputPathError

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

logger = logging.getLogger(__name__)

PARTIAL_MARK = ".hoap-partial"

__all__ = ["PARTIAL_MARK", "check_output_path", "claimed_directory", "claimed_file", "claimed_files", "write_bytes"]


def _path_text(path: str | os.PathLike, what: str, example: str) -> Path:
    """``path`` as a :class:`Path` once it is a name at all: not empty, no NUL (which ``os`` refuses
    with a bare ValueError)."""
    if not str(path).strip():
        raise InvalidInputError(f"the {what} path is empty; give one such as {example}")
    if "\0" in str(path):
        raise InvalidInputError(f"the {what} path {str(path)!r} holds a NUL character, which no file name may hold")
    return Path(path)


def check_output_path(path: str | os.PathLike, what: str = "output") -> Path:
    """``path`` as a :class:`Path` once it names a file that may be written: not empty, not a folder."""
    path = _path_text(path, what, f"out/{what}.ext")
    if path.is_dir():
        raise InvalidInputError(f"the {what} path {path} is a directory; give a file name inside it")
    if path.name in ("", ".", ".."):
        raise InvalidInputError(f"the {what} path {path} does not name a file")
    if path.is_symlink() and not path.exists():
        raise OutputPathError(f"the {what} path {path} is a link to {os.readlink(path)}, which does not exist; give "
                              "the file's own path")
    return path


def write_bytes(path: str | os.PathLike, data: bytes, what: str) -> None:
    """Write ``data`` to ``path`` (a claimed partial) and make sure it reached the disk: a full disk or
    any other write error is an :class:`OutputPathError` naming the file and the cause."""
    try:
        with open(path, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as exc:
        raise OutputPathError(f"could not write the {what} {path}: {exc.strerror or exc}; free some space or "
                              "choose another folder") from None


def _make_folder(folder: Path, what: str) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputPathError(
            f"cannot create the folder {folder} for the {what}: {exc.strerror or exc}; choose a folder you can write to"
        ) from exc
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputPathError(f"the folder {folder} for the {what} is not writable")


class _Claim:
    """An open, locked partial (file or folder); :meth:`release` closes it (the lock goes with it)."""

    def __init__(self, target: Path, partial: Path, folder: bool, what: str) -> None:
        self.partial = partial
        self.folder = folder
        self._fd = self._acquire(target, partial, folder, what)

    @staticmethod
    def _open(partial: Path, folder: bool) -> int:
        if folder:
            with contextlib.suppress(FileExistsError):
                partial.mkdir()
            return os.open(partial, os.O_RDONLY | os.O_DIRECTORY)
        flags = os.O_RDWR | os.O_CREAT | (0 if fcntl else os.O_EXCL)
        return os.open(partial, flags, 0o644)

    def _acquire(self, target: Path, partial: Path, folder: bool, what: str) -> int:
        busy = DataExistsError(
            f"another process is writing the {what} {target} (its partial {partial.name} is locked); "
            "wait for it to finish or choose another path"
        )
        for _ in range(100):  # retried only when the partial is replaced between open and lock
            try:
                fd = self._open(partial, folder)
            except FileExistsError:
                raise busy from None
            except OSError as exc:
                raise OutputPathError(
                    f"cannot write the {what} in {partial.parent}: {exc.strerror or exc}; choose a folder you can "
                    "write to"
                ) from exc
            if fcntl is None:
                return fd
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                os.close(fd)
                if exc.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                    raise busy from None
                raise
            try:
                same = os.stat(partial).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                if not folder:
                    os.ftruncate(fd, 0)  # a stale partial of a killed run: start it afresh
                return fd
            os.close(fd)  # the previous owner published or removed it meanwhile: claim anew
        raise OutputPathError(f"could not claim {partial}: it keeps being replaced")

    def discard(self) -> None:
        if self.folder:
            shutil.rmtree(self.partial, ignore_errors=True)
        else:
            self.partial.unlink(missing_ok=True)

    def release(self) -> None:
        os.close(self._fd)


@contextlib.contextmanager
def _probed(partial: Path) -> Iterator[bool | None]:
    """Try the lock of the claim ``partial``: yields True while this process holds it (a killed run's
    partial), False if a live process holds it, None if it cannot be opened (gone, no permission)."""
    try:
        fd = os.open(partial, os.O_RDONLY | (os.O_DIRECTORY if partial.is_dir() else 0))
    except OSError:
        yield None
        return
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            yield False
        else:
            yield True
    finally:
        os.close(fd)


def _held(partial: Path) -> bool:
    """Whether a live process holds the claim ``partial``."""
    if fcntl is None:
        return False
    with _probed(partial) as free:
        return free is False


def _refuse_if_other_claim(target: Path, partials: list[Path], what: str) -> None:
    """Refuse ``target`` while another kind of claim on the same folder is held (a whole-folder claim
    beside it, or a claim of files inside it): one command's output must not mix with another's."""
    for partial in partials:
        if _held(partial):
            raise DataExistsError(f"another process is writing into {target} (its partial {partial.name} is "
                                  "locked); wait for it to finish or choose another folder")


def _sweep_stale_partials(folder: Path, keep: Path) -> None:
    """Remove partials in ``folder`` whose lock is free: what killed runs left behind."""
    if fcntl is None:
        return
    for stale in folder.glob(f".*{PARTIAL_MARK}*"):
        if stale == keep:
            continue
        with _probed(stale) as free:
            if not free:
                continue  # a live run's partial, or one that is already gone
            if stale.is_dir():
                shutil.rmtree(stale, ignore_errors=True)
            else:
                stale.unlink(missing_ok=True)
            logger.info("removed %s, left by an interrupted run", stale)


def _refuse_existing(path: Path, what: str) -> None:
    raise DataExistsError(f"{path} already exists; pass overwrite=True (--overwrite on the command line) to replace "
                          f"the {what}")


def _publish(source: Path, target: Path, overwrite: bool, what: str) -> None:
    """Move ``source`` to ``target`` atomically; without ``overwrite``, fail if ``target`` exists."""
    if overwrite:
        if target.is_dir():
            raise InvalidInputError(f"{target} is a directory; the {what} cannot replace it")
        os.replace(source, target)
        return
    try:
        os.link(source, target)
    except FileExistsError:
        _refuse_existing(target, what)
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.EXDEV):
            raise
        # a file system without hard links: the claim's lock still excludes other hoap-actions writers
        if target.exists():
            _refuse_existing(target, what)
        os.replace(source, target)
        return
    source.unlink()


@contextlib.contextmanager
def claimed_file(path: str | os.PathLike, overwrite: bool = False, what: str = "output") -> Iterator[Path]:
    """Claim ``path`` for a job that writes it: yields the partial to write to, publishes it on success.

    Checks at entry (before any work): the path names a file, its folder can be created and written,
    the file does not exist (unless ``overwrite``) and no other process is writing it. On an
    exception the partial is removed and ``path`` is untouched.
    """
    path = check_output_path(path, what)
    with _claimed(path, path.with_name(f".{path.stem}{PARTIAL_MARK}{path.suffix}"), False, overwrite, what) as partial:
        yield partial
        _publish(partial, path, overwrite, what)


@contextlib.contextmanager
def _claimed(target: Path, partial: Path, folder: bool, overwrite: bool, what: str) -> Iterator[Path]:
    """The checks and the lock every claim takes at entry; the partial removed and the lock released at exit."""
    _make_folder(target.parent, what)
    claim = _Claim(target, partial, folder=folder, what=what)
    try:
        if target.exists() and not overwrite:
            _refuse_existing(target, what)
        _sweep_stale_partials(target.parent, keep=claim.partial)
        yield claim.partial
    finally:
        claim.discard()
        claim.release()


@contextlib.contextmanager
def claimed_files(
    folder: str | os.PathLike, names: Sequence[str], overwrite: bool = False, what: str = "results"
) -> Iterator[Path]:
    """Claim the files ``names`` inside ``folder`` (other files there are left alone): yields a
    staging folder to write them to; all of them are published together on success.

    The same checks as :func:`claimed_file`; a folder this call created is removed again if the job fails.
    Publishing is journalled in the staging folder, so the files a killed run had published are taken
    back by the next claim, never left to block it.
    """
    folder = _path_text(folder, what, f"out/{what.replace(' ', '-')}")
    if folder.exists() and not folder.is_dir():
        raise InvalidInputError(f"{folder} exists and is not a directory; the {what} need a folder")
    created = not folder.exists()
    _make_folder(folder, what)
    claim = None
    published: list[Path] = []
    try:
        claim = _Claim(folder, folder / f".{what.replace(' ', '-')}{PARTIAL_MARK}", folder=True, what=what)
        _refuse_if_other_claim(folder, [folder.with_name(f".{folder.name}{PARTIAL_MARK}")], what)
        _take_back_interrupted_publishing(claim.partial, folder)
        existing = [name for name in names if (folder / name).exists()]
        if existing and not overwrite:
            raise DataExistsError(
                f"{folder} already holds {what} ({', '.join(existing)}); pass overwrite=True (--overwrite) to replace "
                "them"
            )
        _sweep_stale_partials(folder, keep=claim.partial)
        yield claim.partial
        (claim.partial / _JOURNAL).write_text("\n".join(names))
        for name in names:
            _publish(claim.partial / name, folder / name, overwrite, what)
            published.append(folder / name)
    except BaseException:
        if not overwrite:
            for path in published:  # all or nothing: take back what this run had published
                path.unlink(missing_ok=True)
        raise
    finally:
        if claim is not None:
            claim.discard()
            claim.release()
        if created:
            with contextlib.suppress(OSError):
                folder.rmdir()  # only succeeds if this run left it empty


_JOURNAL = ".publishing"  # in a claimed_files staging folder: the names being published


def _take_back_interrupted_publishing(staging: Path, folder: Path) -> None:
    """Remove the files a killed run had begun to publish from ``staging`` (its journal names them), and
    what it left in ``staging``: the claim now held starts afresh."""
    journal = staging / _JOURNAL
    if journal.is_file():
        for name in journal.read_text().split("\n"):
            source, target = staging / name, folder / name
            if name and target.exists() and (not source.exists() or os.path.samefile(source, target)):
                target.unlink()  # published (or being linked) when the run was killed
                logger.info("removed %s, published by an interrupted run", target)
    for leftover in staging.iterdir():
        shutil.rmtree(leftover) if leftover.is_dir() else leftover.unlink()


@contextlib.contextmanager
def claimed_directory(path: str | os.PathLike, overwrite: bool = False, what: str = "directory",
                      foreign: Callable[[Path], list[str]] | None = None) -> Iterator[Path]:
    """Claim the directory ``path`` as a whole (e.g. a models directory, whose file names depend on
    what was learned): yields an empty staging folder beside it, which replaces ``path`` in one rename
    on success.

    The same checks as :func:`claimed_file`; without ``overwrite`` an existing ``path`` is refused, with
    it the old directory is removed only once the new one is in place, and only if it holds nothing
    but what such a directory holds: ``foreign(path)`` names the entries it does not (a recording, the
    command's own inputs, another program's files), and any makes the claim fail before the work.
    """
    path = _path_text(path, what, f"out/{what.replace(' ', '-')}")
    if path.exists() and not path.is_dir():
        raise InvalidInputError(f"{path} exists and is not a directory; the {what} need a folder of their own")
    if path.name in ("", ".", ".."):
        raise InvalidInputError(f"the {what} path {path} does not name a folder")
    if overwrite and path.is_dir():
        strangers = sorted(os.listdir(path)) if foreign is None else foreign(path)
        if strangers:
            shown = ", ".join(strangers[:5]) + (f" and {len(strangers) - 5} more" if len(strangers) > 5 else "")
            raise DataExistsError(f"{path} holds what is not {what} ({shown}); --overwrite (overwrite=True) replaces "
                                  f"only a folder of {what}: give a new or empty folder")
    with _claimed(path, path.with_name(f".{path.name}{PARTIAL_MARK}"), True, overwrite, what) as staging:
        if path.is_dir():
            _refuse_if_other_claim(path, sorted(path.glob(f".*{PARTIAL_MARK}*")), what)
        for leftover in staging.iterdir():  # a killed run's files: start afresh
            shutil.rmtree(leftover) if leftover.is_dir() else leftover.unlink()
        yield staging
        if path.exists() and overwrite:
            old = path.with_name(f".{path.name}.hoap-replaced-{os.getpid()}")
            os.rename(path, old)
            os.rename(staging, path)
            shutil.rmtree(old, ignore_errors=True)
        else:
            try:
                os.rename(staging, path)
            except OSError as exc:
                if exc.errno in (errno.ENOTEMPTY, errno.EEXIST):
                    _refuse_existing(path, what)
                raise
