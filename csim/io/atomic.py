"""Files written whole or not at all: a temporary file beside the target, renamed over it.

Every file csim writes (results, comparisons, sweeps, JUnit reports, the JSON schema, the
example cases) goes through :func:`write_atomically`, or, for a writer that wants a path of
its own (figures, exported tables, animations), :func:`atomic_path`. A failure while
writing (a full disk, ``ulimit -f``, a vanished folder) is an ``OSError`` naming the cause,
the temporary file is removed, and the target is left as it was. The rename replaces a
symbolic link at the target by the file; it never writes through the link into the file it
points at. A new file gets the
mode any new file gets (0666 less the umask, 0644 under the usual umask 022), not
``mkstemp``'s 0600.
"""
from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

#: bytes written per ``os.write`` call
CHUNK = 1 << 24


def _new_file_mode(path: str) -> None:
    """Give ``path`` the mode of a new file under the umask (``mkstemp`` makes it 0600)."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, 0o666 & ~umask)


@contextmanager
def atomic_path(path: str | Path, keep_suffix: bool = True) -> Iterator[Path]:
    """A temporary path beside ``path`` for a writer to fill; renamed over ``path`` when the
    block ends without an exception, removed when it raises.

    The temporary file (``.STEM.XXXXXXXX.SUFFIX``) keeps the suffix of ``path``, for writers
    that pick the format from it (matplotlib's ``savefig``); with ``keep_suffix=False`` it is
    ``.NAME.XXXXXXXX.tmp``. A symbolic link at ``path`` is replaced by the file, never
    written through.

    Parameters
    ----------
    path : str or Path
        The target; its folder is created when missing.
    keep_suffix : bool
        Whether the temporary file ends with the suffix of ``path``.

    Yields
    ------
    Path
        The temporary file (already created, empty) to write.

    Raises
    ------
    OSError
        When the folder cannot be created, or from the writer (a full disk, ``ulimit -f``):
        no temporary file is left and ``path`` is as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    prefix, suffix = (f".{path.stem}.", path.suffix) if keep_suffix else (f".{path.name}.", ".tmp")
    fd, tmp = tempfile.mkstemp(prefix=prefix, suffix=suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)  # durable before it becomes visible
        finally:
            os.close(fd)
        _new_file_mode(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_atomically(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file beside it, then rename it over ``path``
    (:func:`atomic_path`, the temporary file named ``.NAME.XXXXXXXX.tmp``).

    Parameters
    ----------
    path : str or Path
        The target; its folder is created when missing.
    data : bytes
        The whole content.

    Raises
    ------
    OSError
        When the folder cannot be created or the data cannot be written (``errno`` and
        ``strerror`` say why, e.g. EFBIG "File too large", ENOSPC "No space left on
        device"); no temporary file is left and ``path`` is as it was.
    """
    with atomic_path(path, keep_suffix=False) as tmp:
        fd = os.open(tmp, os.O_WRONLY)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view[:CHUNK]):]
        finally:
            os.close(fd)
