"""Safe names: what a site, hoist, rig or parameter set may be called, and paths built of them.

Names that come from input data (a CSV header's ``site``/``hoist``, a TDMS file
property, an MCAP ``/rig/info`` ``rig_id``, a hoist description's ``[hoist] site`` /
``name`` and ``[friction] parameter_set``, calibrate's ``--rig`` / ``--parameter-set``)
become folder names under the data root (``lake/<table>/site=<site>/hoist=<hoist>/``,
``reports/discovery/<site>_<hoist>_<day>.json``) and partition keys. So every such
name must be one plain path component that means nothing special to a file system or
to Hive partitioning:

    **1 to 64 characters of** ``A-Z a-z 0-9 . _ -`` **, starting with a letter or a
    digit, and without ``..``** (regular expression :data:`NAME_PATTERN`).

That rules out ``/`` and ``\\`` (a path inside a name), ``..`` and a leading dot
(parent folders, hidden files), absolute paths, ``=`` and ``%`` (Hive partition
syntax), spaces, NUL, newlines and every other control character. ``xuzhou-north``,
``main-shaft-1``, ``rig_a.2`` are names; ``../../x``, ``a/b``, ``/tmp/x``, ``.hidden``,
``main shaft`` are not.

:func:`safe_name` checks a name at the edge where it enters (a reader, the hoist
loader, the command line) and raises :class:`UnsafeNameError` with one line naming
the source (file), the key and the value (``repr``, so a NUL or a newline is
visible). Defence in depth: :func:`join_inside` builds a path below a base folder
from path components and raises :class:`PathEscapeError` if the result, symlinks
resolved, is not inside that folder; :class:`warehouse.store.DataRoot` builds every
path it hands out from data through it.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

__all__ = [
    "MAX_NAME_LENGTH",
    "NAME_PATTERN",
    "NAME_RULE",
    "PathEscapeError",
    "UnsafeNameError",
    "escape_error",
    "escaping_links",
    "escaping_paths",
    "is_safe_name",
    "join_inside",
    "name_problem",
    "printable",
    "safe_name",
    "undecodable",
]

MAX_NAME_LENGTH = 64
#: A safe name, whole (use ``fullmatch``); ``..`` is excluded separately.
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
#: The rule in words, for error messages.
NAME_RULE = (
    "a name is 1-64 characters of A-Z a-z 0-9 . _ -, starts with a letter or digit and has no '..'"
)
#: One path component built from safe names (``site=<site>``, ``<site>_<hoist>_<day>.json``).
_PART_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._=-]{0,254}")
_ALLOWED = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._-")


class UnsafeNameError(ValueError):
    """A name that could leave the data root or break a partition key; one-line message."""


class PathEscapeError(ValueError):
    """A path built under a base folder that resolves outside it (e.g. through a symlink)."""


def name_problem(value: object) -> str | None:
    """Why ``value`` is not a safe name (one line, shows the value with ``repr``), or None."""
    if not isinstance(value, str):
        return f"not a string: {value!r} ({type(value).__name__})"
    if NAME_PATTERN.fullmatch(value) and ".." not in value:
        return None
    bad = next((c for c in value if c not in _ALLOWED), None)
    if not value:
        reason = "empty"
    elif ".." in value:
        reason = "contains '..'"
    elif bad is not None:
        reason = f"character {bad!r} not allowed"
    elif len(value) > MAX_NAME_LENGTH:
        reason = f"{len(value)} characters, more than {MAX_NAME_LENGTH}"
    else:
        reason = f"starts with {value[0]!r}"
    return f"unsafe name {value!r}: {reason}; {NAME_RULE}"


def is_safe_name(value: object) -> bool:
    """Whether ``value`` is a safe name (see the module docstring)."""
    return name_problem(value) is None


def safe_name(value: object, *, key: str, source: str) -> str:
    """Return ``value`` if it is a safe name, else raise :class:`UnsafeNameError`.

    ``source`` names where the value was read (a file, ``file: line 2``, a command
    option's command) and ``key`` what it is (``site``, ``file property 'hoist'``);
    the message is ``"<source>: <key>: unsafe name '<value>': <why>; <the rule>"``.

    >>> safe_name("main-shaft-1", key="hoist", source="log.csv")
    'main-shaft-1'
    >>> safe_name("../x", key="site", source="log.csv")
    Traceback (most recent call last):
    ...
    schemas.names.UnsafeNameError: log.csv: site: unsafe name '../x': contains '..'; ...
    """
    problem = name_problem(value)
    if problem is not None:
        raise UnsafeNameError(f"{source}: {key}: {problem}")
    return value  # type: ignore[return-value]  # name_problem checked it is a str


def _inside(base: Path, path: Path) -> bool:
    return path == base or path.is_relative_to(base)


def join_inside(base: str | os.PathLike[str], *parts: str, source: str = "path") -> Path:
    """``base / part / ...``, refused unless it stays inside ``base``.

    Each part must be one plain path component of safe-name characters (``=`` also
    allowed, for Hive ``key=value`` folders; up to 255 characters, no ``..``), else
    :class:`UnsafeNameError`. Then the joined path and ``base`` are resolved (symlinks
    followed, as far as they exist) and the path must be ``base`` or below it, else
    :class:`PathEscapeError` -- a symlink planted inside the data root that points
    elsewhere is refused. ``base`` itself may be a symlink (a lake on another disk).
    Returns the joined, unresolved path.
    """
    base = Path(base)
    for part in parts:
        if not isinstance(part, str) or not _PART_PATTERN.fullmatch(part) or ".." in part:
            raise UnsafeNameError(
                f"{source}: path component {part!r} under {base} is not a plain name "
                "(A-Z a-z 0-9 . _ - =, no '..', not starting with '.')"
            )
    path = base.joinpath(*parts)
    real_base = base.resolve()
    real = path.resolve()
    if not _inside(real_base, real):
        raise PathEscapeError(f"{source}: {path} resolves to {real}, outside {real_base}")
    return path


def printable(value: object) -> str:
    """``value`` (a path, a name) as text fit for one line of a message or a table.

    A file name may hold any byte but ``/`` and NUL: a line break would split a one-line
    error in two and an escape sequence would reach the terminal. Characters that are
    not printable are shown as Python escapes, and bytes that are not UTF-8 (which
    Python keeps as lone surrogates) as ``\\xNN``; everything else is left as it is.

    >>> printable("/in/bad\\nname.csv")
    '/in/bad\\\\nname.csv'
    >>> printable("/in/k\\udcff.csv")
    '/in/k\\\\xff.csv'
    """
    text = str(value)
    if text.isprintable():
        return text
    text = text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode() for c in text)


def escaping_links(base: str | os.PathLike[str]) -> list[tuple[Path, Path]]:
    """(link, where it resolves) of every symlink below ``base`` (the folder's tree,
    links not followed) that resolves outside ``base``; ``base`` itself may be a link.

    The readers' side of :func:`join_inside`: a lake table's readers glob its partitions
    and would follow a link planted there to files elsewhere.
    """
    base = Path(base)
    real_base = base.resolve()
    found: list[tuple[Path, Path]] = []
    folders = [os.fspath(base)]
    # directory entries only (no stat per file) and strings, not paths: a lake has many
    # files
    while folders:
        with os.scandir(folders.pop()) as entries:
            for entry in entries:
                if entry.is_symlink():
                    real = Path(entry.path).resolve()
                    if not _inside(real_base, real):
                        found.append((Path(entry.path), real))
                elif entry.is_dir(follow_symlinks=False):
                    folders.append(entry.path)
    return sorted(found)


def escaping_paths(base: str | os.PathLike[str], paths: list[Path]) -> list[tuple[Path, Path]]:
    """(path, where it resolves) of those of ``paths`` that resolve outside ``base``
    (the files a reader selected; :func:`escaping_links` walks a whole tree instead)."""
    real_base = Path(base).resolve()
    resolved = ((path, path.resolve()) for path in paths)
    return [(path, real) for path, real in resolved if not _inside(real_base, real)]


def escape_error(what: str, escaped: list[tuple[Path, Path]]) -> PathEscapeError:
    """The one-line refusal of ``what`` (e.g. ``lake table 'field_samples'``) holding the
    links or files ``escaped`` (:func:`escaping_links`, :func:`escaping_paths`)."""
    link, real = escaped[0]
    more = f" (and {len(escaped) - 1} more link(s))" if len(escaped) > 1 else ""
    return PathEscapeError(f"{what}: {link} resolves to {real}, outside it{more}")


def undecodable(text: str) -> str | None:
    """What in ``text`` is not UTF-8 (a name's bytes that are not, which Python keeps as
    lone surrogates: ``'byte 0xff'``), or None when it all is.

    >>> undecodable("k\\udcff.csv")
    'byte 0xff'
    >>> undecodable("k.csv") is None
    True
    """
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as exc:
        byte = ord(text[exc.start]) - 0xDC00
        return f"byte 0x{byte:02x}" if 0x80 <= byte <= 0xFF else "a lone surrogate"
    return None
