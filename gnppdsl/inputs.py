"""Reading the files a user names: regular files only, bounded in size, UTF-8 located on error.

Why one helper for every read of user input (.pntc, scene YAML, the URDF a scene names):
- `open()` of a FIFO blocks until a writer appears and `read()` of `/dev/zero` never ends, so a
  path is opened with O_NONBLOCK and refused unless `fstat` says it is a regular file;
- a file larger than `MAX_INPUT_BYTES` is refused before it is read (a mistaken `scene` line
  pointing at a disk image must not exhaust memory);
- what may be *echoed* in a diagnostic is decided here too: only files with a suffix the user
  writes (`.pntc`, `.yaml`/`.yml`, `.urdf`/`.srdf`/`.xml`) are read at all, so a mistaken
  `scene "/etc/shadow"` is refused by its name and never shows up in a report;
- a path with a NUL byte, a name too long for the file system or any other OS error becomes a
  message, never an exception (`ValueError`/`OSError` from `os.open`).
Invalid UTF-8 is reported at the line and column of the first bad byte (`InputError.line`).
"""
from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from gnppdsl.errors import UserError

#: the largest .pntc / scene / URDF file read (bytes); the bundled Lab domain is 9 KB, the
#: Panda URDF 20 KB: 8 MiB leaves room for generated problems with thousands of objects
MAX_INPUT_BYTES = 8 * 1024 * 1024
#: the largest `.pntc` source read (bytes): parsing costs about 25 us of CPU per byte of
#: dense tokens (a 400 KB one-line fuzz mutant took 10 s to parse and 13 s to check), so a
#: source this size is checked in about 6 s; the largest bundled `.pntc` is under 20 KB, and
#: 256 KiB still holds problems with several thousand objects
MAX_SOURCE_BYTES = 256 * 1024

SOURCE_SUFFIXES = (".pntc",)
SCENE_SUFFIXES = (".yaml", ".yml")
ROBOT_SUFFIXES = (".urdf", ".srdf", ".xml")


class InputError(UserError):
    """A file that cannot be used as input. `line`/`column` locate a decoding error inside it."""

    def __init__(self, message: str, line: int | None = None, column: int | None = None,
                 text: str | None = None, too_large: bool = False) -> None:
        super().__init__(message)
        self.message = message
        self.too_large = too_large  # the file itself is at fault (reported at its 1:1)
        self.line = line
        self.column = column
        self.text = text            # the file decoded with replacement characters (for the echo)


_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))


def describe_os_error(exc: BaseException) -> str:
    """`OSError`/`ValueError` of a path operation as a short phrase (no Python names)."""
    if isinstance(exc, ValueError):
        return "the path contains a NUL byte" if "null" in str(exc).lower() else str(exc)
    if isinstance(exc, OSError):
        if exc.errno == errno.ENAMETOOLONG:
            return "the file name is too long"
        if exc.errno == errno.ENOENT:
            return "no such file"
        if exc.errno in (errno.EACCES, errno.EPERM):
            return "permission denied"
        if exc.errno == errno.ELOOP:
            return "too many levels of symbolic links"
        return exc.strerror or str(exc)
    return str(exc)


def read_bytes(path: str | Path, max_bytes: int | None = None) -> bytes:
    """The bytes of a regular file of at most `max_bytes` (default `MAX_INPUT_BYTES`), else
    `InputError`."""
    max_bytes = MAX_INPUT_BYTES if max_bytes is None else max_bytes
    p = os.fspath(path)
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | getattr(os, "O_CLOEXEC", 0))
    except (OSError, ValueError) as exc:
        raise InputError(describe_os_error(exc)) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            what = next((w for test, w in _KINDS if test(st.st_mode)), "not a regular file")
            raise InputError(f"{what}, not a regular file")
        if st.st_size > max_bytes:
            raise InputError(f"{st.st_size:,} bytes, larger than the limit of {max_bytes:,} bytes",
                             too_large=True)
        chunks = []
        total = 0
        while True:                      # a file growing while read is still bounded
            chunk = os.read(fd, min(1 << 20, max_bytes + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
            if total > max_bytes:
                raise InputError(f"larger than the limit of {max_bytes:,} bytes", too_large=True)
        return b"".join(chunks)
    except OSError as exc:
        raise InputError(describe_os_error(exc)) from None
    finally:
        os.close(fd)


def decode_utf8(data: bytes) -> str:
    """UTF-8 text (a leading BOM dropped); `InputError` at the line:col of the first bad byte."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        before = data[: exc.start].decode("utf-8", errors="replace")
        line = before.count("\n") + 1
        column = len(before) - (before.rfind("\n") + 1) + 1
        raise InputError(f"invalid UTF-8 (byte 0x{data[exc.start]:02x}); save the file as UTF-8",
                         line, column, data.decode("utf-8", errors="replace")) from None
    return text[1:] if text.startswith("\ufeff") else text


def check_suffix(path: str | Path, suffixes: tuple[str, ...], what: str) -> None:
    """Refuse a file whose name does not say it is one the user writes (nothing is read)."""
    if Path(os.fspath(path)).suffix.lower() not in suffixes:
        raise InputError(f"a {what} is a {' or '.join(suffixes)} file")


def read_text(path: str | Path, suffixes: tuple[str, ...] | None = None, what: str = "file",
              max_bytes: int | None = None) -> str:
    """`check_suffix` (if `suffixes`), `read_bytes`, `decode_utf8`."""
    if suffixes is not None:
        check_suffix(path, suffixes, what)
    return decode_utf8(read_bytes(path, max_bytes))


def is_regular_file(path: str | Path) -> bool:
    """`Path.is_file` that says False instead of raising for a NUL byte or an over-long name."""
    try:
        return stat.S_ISREG(os.stat(os.fspath(path)).st_mode)
    except (OSError, ValueError):
        return False


def file_digest(path: str | Path | None) -> str:
    """SHA-256 of a file's bytes, for cache keys that must change when a file is edited between
    two processes (a robot's URDF and SRDF); "-" for no path, "unreadable PATH" when it
    cannot be read (the key then still differs from a readable file's)."""
    import hashlib

    if not path:
        return "-"
    try:
        return hashlib.sha256(read_bytes(path)).hexdigest()
    except InputError:
        return f"unreadable {path}"
