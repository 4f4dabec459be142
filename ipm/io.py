"""Atomic file writes: a reader (or a killed run) never sees a half-written file."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it is renamed onto ``path``.

    On an exception the temporary file is removed and ``path`` is left as it was.  The
    temporary name keeps the suffix so that writers which pick a format by suffix work.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}",
                               dir=path.parent)
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp's 0600 would hide outputs from others
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def check_same_settings(path: Path, settings: dict, what: str) -> None:
    """Raise a :class:`~ipm.errors.UserError` if ``path`` holds other settings than
    ``settings``: a resumable command refuses to mix two runs in one folder."""
    import json

    from ipm.errors import UserError

    if path.is_file() and json.loads(path.read_text(encoding="utf-8")) != settings:
        raise UserError(f"the folder of {path} holds {what} made with other settings; "
                        "choose another --out or delete it")


def check_writable_folder(folder: Path) -> None:
    """Raise a :class:`~ipm.errors.UserError` naming ``folder`` unless it exists and is
    writable: a command checks this before any work, so it fails before writing anything."""
    from ipm.errors import UserError

    if not folder.is_dir():
        raise UserError(f"output folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise UserError(f"output folder {folder} is not writable")


def check_output(path: Path) -> None:
    """Fail before any work if the file ``path`` cannot be written (it is a folder, or its
    folder is missing or read-only)."""
    from ipm.errors import UserError

    if Path(path).is_dir():
        raise UserError(f"{path} is a folder; give a file name")
    check_writable_folder(path.parent if str(path.parent) else Path("."))


def check_not_inputs(outputs: list[Path], inputs: list[Path | None], force: bool = False
                     ) -> None:
    """Refuse, before any work, to write over a file the command reads (``ipm render y.json
    -o y.png`` would replace y.json with its sidecar; ``ipm edit g.json -o g.json`` a
    render's sidecar with bare parameters), unless ``force`` (``--force``)."""
    from ipm.errors import UserError

    if force:
        return
    given = {_resolved(p) for p in inputs if p is not None}
    for out in outputs:
        if _resolved(out) in given:
            raise UserError(f"{out} is an input of this command; choose another output, or "
                            "give --force to write over it")


def _resolved(path: str | os.PathLike) -> Path:
    """``path`` made absolute with its links followed; a link loop stays as it is named
    (pathlib raises RuntimeError on one)."""
    try:
        return Path(path).resolve()
    except (RuntimeError, OSError):
        return Path(os.path.abspath(path))


def check_regular_file(path: str | os.PathLike, what: str = "") -> None:
    """A one-line :class:`~ipm.errors.UserError` unless ``path`` is a regular file (or a
    link to one): a missing file, a link loop, and a FIFO, device or socket (reading one
    would block or never end) are named."""
    import errno
    import stat

    from ipm.errors import UserError

    name = os.fspath(path)
    try:
        mode = os.stat(name).st_mode
    except FileNotFoundError:
        raise UserError(f"{name}: no such file") from None
    except OSError as e:
        why = "a symbolic link loop" if e.errno == errno.ELOOP else e.strerror
        raise UserError(f"{name}: cannot open it ({why})") from None
    if stat.S_ISDIR(mode):
        raise UserError(f"{name} is a folder, not {what or 'a file'}")
    if not stat.S_ISREG(mode):
        raise UserError(f"{name} is not a regular file (a FIFO, device or socket); give "
                        f"{what or 'a file'}")


def prepare_folder(folder: Path, what: str = "output folder") -> None:
    """Create ``folder`` (and its parents) if needed and check that it is writable; a
    :class:`~ipm.errors.UserError` names it otherwise."""
    from ipm.errors import UserError

    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UserError(f"cannot create {what} {folder}: {e.strerror}") from None
    check_writable_folder(folder)


def write_text(path: str | os.PathLike, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def write_bytes(path: str | os.PathLike, data: bytes) -> None:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def content_hash(path: str | os.PathLike) -> str | None:
    """The SHA-256 of a photo's bytes, or None for one that is not a readable regular file
    (never read: a FIFO would block)."""
    import hashlib
    import stat

    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return None
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        return h.hexdigest()
    except OSError:
        return None
