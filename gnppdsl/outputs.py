"""Writing files: atomically, never through a symbolic link, caches private to the user.

Why one helper for every file gnpp writes (`--json`, `--render`, `compile -o`, `bench --csv`,
the parse cache):
- a reader (or a crash) never sees half a file: the data goes to a temporary file in the same
  directory, is flushed to disk (`fsync`) and renamed over the final name, then the directory
  is synced so the rename survives a power cut;
- the temporary name is fresh and created with `O_CREAT | O_EXCL | O_NOFOLLOW`, so a symbolic
  link planted at a predictable name (the old `res.json.tmp`) is never followed;
- a final name that is a symbolic link, a directory or a device is refused, not replaced:
  `--json ~/.bashrc-link` must not redirect the result into another file, and nothing a user
  saved is ever overwritten through a link (a regular file the user names is replaced: that
  is the request);
- cache directories are created 0700 and refused when another user owns them, so a planted
  cache entry cannot come from someone else.
Errors are `UserError`s that name the option (`--json res.json: ...`), exit 2.
"""
from __future__ import annotations

import os
import stat
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Iterator

from gnppdsl.errors import UserError


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _no_nul(path: str | Path, what: str) -> Path:
    p = Path(os.fspath(path))
    if "\0" in str(p):
        raise UserError(f"{what}: the path contains a NUL byte")
    return p


def _lstat_not_a_link(p: Path, what: str, doing: str) -> os.stat_result | None:
    """What is at `p` (not following a link), None if nothing; a symbolic link or an
    unreadable name is refused (`doing` prefixes the OS reason). The one place both writers,
    files (`check_target`) and directories (`output_dir`), refuse links."""
    try:
        st = os.lstat(p)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise UserError(f"{what} {p}: {doing}{_reason(exc)}") from None
    if stat.S_ISLNK(st.st_mode):
        raise UserError(f"{what} {p}: is a symbolic link; gnpp does not write through links")
    return st


def check_target(path: str | Path, what: str, parent_may_be_missing: bool = False) -> Path:
    """`path` as a place to write a file: its directory exists (unless
    `parent_may_be_missing`: the caller creates it), and the name is free or a regular file
    (not a symbolic link, directory, FIFO or device). Nothing is created."""
    p = _no_nul(path, what)
    parent = p.parent if str(p.parent) else Path(".")
    try:
        if not stat.S_ISDIR(os.stat(parent).st_mode):
            raise UserError(f"{what} {p}: {parent} is not a directory")
    except FileNotFoundError:
        if parent_may_be_missing:
            return p
        raise UserError(f"{what} {p}: directory {parent} does not exist") from None
    except OSError as exc:
        raise UserError(f"{what} {p}: {_reason(exc)}") from None
    st = _lstat_not_a_link(p, what, "")
    if st is None:
        return p
    if not stat.S_ISREG(st.st_mode):
        raise UserError(f"{what} {p}: exists and is not a regular file")
    return p


@contextmanager
def atomic_open(path: str | Path, what: str, binary: bool = False, newline: str | None = None,
                mode: int = 0o644) -> Iterator[IO]:
    """A file object whose content replaces `path` when the block ends without an exception
    (temporary file, fsync, rename); on an exception the temporary file is removed and `path`
    is left as it was. `mode` is applied through the umask, as `open()` does."""
    p = check_target(path, what)
    parent = p.parent if str(p.parent) else Path(".")
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    for _ in range(100):
        tmp = parent / f".{p.name[:200]}.{os.urandom(6).hex()}.tmp"
        try:
            fd = os.open(tmp, flags, mode)
            break
        except FileExistsError:
            continue
        except OSError as exc:
            raise UserError(f"{what} {p}: cannot write: {_reason(exc)}") from None
    else:  # pragma: no cover - 100 collisions of 48 random bits
        raise UserError(f"{what} {p}: cannot create a temporary file")
    try:
        fh = os.fdopen(fd, "wb" if binary else "w", **({} if binary else {"encoding": "utf-8", "newline": newline}))
    except BaseException:
        os.close(fd)
        os.unlink(tmp)
        raise
    try:
        with fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        check_target(p, what)                # still not a link (planted while we wrote)
        os.replace(tmp, p)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise UserError(f"{what} {p}: cannot write: {_reason(exc)}") from None
        raise
    _sync_dir(parent)


def write_atomic(path: str | Path, data: str | bytes, what: str, mode: int = 0o644) -> Path:
    """Replace `path` by `data` atomically (see `atomic_open`); returns the path."""
    with atomic_open(path, what, binary=isinstance(data, bytes), mode=mode) as fh:
        fh.write(data)
    return Path(path)


def output_dir(path: str | Path, what: str) -> Path:
    """A directory to write into (`--render DIR`, `compile -o DIR`), created if missing; a
    symbolic link or a file at that name is refused."""
    p = _no_nul(path, what)
    st = _lstat_not_a_link(p, what, "cannot create the directory: ")
    if st is None:
        try:
            p.mkdir(parents=True)
        except OSError as exc:
            raise UserError(f"{what} {p}: cannot create the directory: {_reason(exc)}") from None
        return p
    if not stat.S_ISDIR(st.st_mode):
        raise UserError(f"{what} {p}: exists and is not a directory")
    return p


def cache_directory(env_var: str, name: str) -> Path | None:
    """Where a cache of gnppdsl's lives: the directory `env_var` names (`0`, `off`, `no`,
    `false` or empty: no cache, None), else `$XDG_CACHE_HOME/gnppdsl/<name>`, else
    `~/.cache/gnppdsl/<name>`, else (no home directory) one under the temporary directory,
    which `private_dir` accepts only when this user made it."""
    env = os.environ.get(env_var)
    if env is not None:
        return None if env.strip().lower() in ("", "0", "off", "no", "false") else Path(env)
    base = os.environ.get("XDG_CACHE_HOME")
    if base:
        return Path(base) / "gnppdsl" / name
    try:
        return Path.home() / ".cache" / "gnppdsl" / name
    except RuntimeError:           # no home directory (HOME unset, no passwd entry)
        import tempfile
        return Path(tempfile.gettempdir()) / f"gnppdsl-{name}"


def private_dir(path: str | Path) -> Path | None:
    """A cache directory of this user with mode 0700 (created, or tightened if it is ours);
    None when it cannot be made private (owned by another user, a symbolic link, not a
    directory): the caller then works without the cache."""
    p = Path(os.fspath(path))
    try:
        p.mkdir(parents=True, exist_ok=True, mode=0o700)
        st = os.lstat(p)
        if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid():
            return None
        if stat.S_IMODE(st.st_mode) != 0o700:
            os.chmod(p, 0o700)
    except (OSError, ValueError):
        return None
    return p


def _sync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
