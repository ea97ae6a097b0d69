"""The one reader of every YAML and JSON file the package reads, and of ``--set KEY=VALUE`` values.

Env configs (:mod:`pneunet_env.config`), train configs (:mod:`agents.training.config`), the object catalogue
(:mod:`pneunet_env.catalogue`), saved schedules (:func:`agents.policies.scripted.load_ramp`), model sidecars and
normalisation statistics (:mod:`agents.policies`), and each ``--set`` value are read here, by the same rules:

* **Plain data only.** Mappings, sequences, strings, integers, floats, booleans and null; no Python object is ever
  built. An explicit tag other than these (``!!python/object``, ``!!binary``, ``!!set``, ``!!timestamp``, ...)
  is refused; dates such as ``2024-01-31`` are read as strings.
* **Duplicate keys are refused**, naming the key, the file and the line (in JSON, the line of the object that
  holds it). Keys equal as values are duplicates: ``1`` and ``1.0``, ``a`` and ``"a"``.
* **Numbers: the forms of YAML 1.2 and of YAML 1.1, the same in a file and in** ``--set``. ``3e-4``, ``5e1``,
  ``1E3``, ``1.0e+3``, ``.5``, ``1.`` and ``1_000.5`` are floats (PyYAML alone, which follows YAML 1.1, reads
  ``3e-4`` and ``5e1`` as strings); ``.inf``, ``-.inf`` and ``.nan`` are the special floats (a config key then
  refuses them by name); ``1_000``, ``0x1F``, ``0o17`` and ``0b101`` are integers. The two forms whose value the
  two YAML versions disagree on are refused with an error naming them rather than guessed: an integer with a leading
  zero (``017``: octal 15 in YAML 1.1, 17 in YAML 1.2) and a colon-separated number (``1:30``: 90 in YAML 1.1, a
  string in 1.2). Quote them for a string, or write ``0o17`` / ``17``.
* **Booleans: ``true`` and ``false``** (``true``, ``True``, ``TRUE``; the same for false): the booleans of YAML 1.2
  and of YAML 1.1 alike. ``yes``/``no``/``on``/``off`` (any of the three capitalisations) are booleans in YAML 1.1
  (PyYAML, rl-zoo3) and strings in YAML 1.2: like the ambiguous numbers below, they are refused with an error naming
  the key (or the line) and saying ``write true or false`` (quote them for a string). So a file, ``--set`` and a
  keyword argument take the same booleans: a config's boolean key takes ``true``/``false`` or a Python ``bool``
  only (:func:`pneunet_env.config.check_bool` refuses ``"yes"``, ``1`` and ``0`` too).
* **Null as YAML reads it:** ``null`` (any of the three capitalisations), ``~`` and the empty value.
* **Bounded.** A document over :data:`MAX_INPUT_BYTES` (JSON: :data:`MAX_JSON_BYTES`), nested deeper than
  :data:`MAX_DEPTH`, with more than :data:`MAX_ALIASES` aliases, or whose aliases would expand it past
  :data:`MAX_EXPANDED_SIZE` (about that many characters, a "billion laughs" alias bomb) is refused as it is read,
  before anything is expanded. A recursive alias (``&a [*a]``) is refused.
* **Regular files only.** A path that is a folder, a FIFO (opening it would wait for a writer for ever), a device
  (``/dev/zero`` never ends) or a socket, or that is too long for the file system, is refused by name before it is
  opened (:func:`check_input_file`; it is opened without blocking all the same).
* **Named errors.** Every problem is a ``ValueError`` naming the source (the file's path, or ``--set 'KEY=VALUE'``)
  and, for a syntax error, the line and column; no ``yaml`` or ``json`` exception escapes. A value quoted in a
  message is cut past :data:`SHOWN_CHARS` characters (:func:`short_repr`, :func:`cut_message`): its start, and its
  length.

:func:`dump_yaml` writes YAML that this reader reads back to the same values (a string that would read as a number
is quoted).
"""

from __future__ import annotations

import functools
import json
import json.decoder
import json.scanner
import math
import os
import re
import stat
from typing import Any

import yaml
from yaml.constructor import ConstructorError
from yaml.nodes import MappingNode, ScalarNode, SequenceNode

__all__ = [
    "check_input_file",
    "cut_message",
    "file_kind",
    "path_too_long",
    "short_repr",
    "load_yaml",
    "load_yaml_file",
    "parse_value",
    "load_json",
    "load_json_file",
    "dump_yaml",
    "MAX_INPUT_BYTES",
    "MAX_JSON_BYTES",
    "MAX_DEPTH",
    "MAX_ALIASES",
    "MAX_EXPANDED_SIZE",
    "MAX_MESSAGE_CHARS",
    "SHOWN_CHARS",
]

MAX_INPUT_BYTES = 256 << 10
"""Largest YAML document read (256 KiB, a few seconds of PyYAML's pure-Python parser; the largest file the package
ships, ``objects.yaml``, is about 35 kB)."""

MAX_JSON_BYTES = 8 << 20
"""Largest JSON document read (8 MiB)."""

MAX_DEPTH = 100
"""Deepest nesting of sequences and mappings."""

MAX_ALIASES = 1000
"""Most aliases (``*name``) in one YAML document."""

MAX_EXPANDED_SIZE = 4_000_000
"""Largest size of a YAML document with every alias expanded: each node counts 1, and a scalar its characters too."""

_TAG = "tag:yaml.org,2002:"
_AMBIGUOUS_TAG = "tag:pneunet-env,2025:ambiguous-number"

_AMBIGUOUS_BOOL_TAG = "tag:pneunet-env,2025:ambiguous-bool"

_BOOL = {"true": True, "false": False}

# Implicit types of plain scalars, in the order they are tried (for scalars starting with the same character).
_RESOLVERS: list[tuple[str, str, str]] = [
    (_TAG + "bool", r"^(?:true|True|TRUE|false|False|FALSE)$", "tTfF"),
    # YAML 1.1's other booleans, strings in YAML 1.2: refused (see the module)
    (_AMBIGUOUS_BOOL_TAG, r"^(?:yes|Yes|YES|no|No|NO|on|On|ON|off|Off|OFF)$", "yYnNoO"),
    (_TAG + "null", r"^(?:~|null|Null|NULL|)$", "~nN"),
    (_TAG + "int", r"^[-+]?(?:0|[1-9][0-9_]*|0b[01_]*[01][01_]*|0o[0-7_]*[0-7][0-7_]*"
                   r"|0x[0-9a-fA-F_]*[0-9a-fA-F][0-9a-fA-F_]*)$", "-+0123456789"),
    # the YAML 1.1 / 1.2 disagreements: a leading zero (octal or decimal?), a colon (base 60 or a string?)
    (_AMBIGUOUS_TAG, r"^[-+]?(?:0[0-9_]+|[0-9][0-9_]*(?::[0-9_]+)+(?:\.[0-9_]*)?)$", "-+0123456789"),
    (_TAG + "float", r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)?$"
                     r"|^[-+]?\.(?:inf|Inf|INF)$|^\.(?:nan|NaN|NAN)$", "-+.0123456789"),
    (_TAG + "merge", r"^<<$", "<"),
]


def _add_resolvers(cls: type) -> None:
    cls.yaml_implicit_resolvers = {}
    for tag, pattern, first in _RESOLVERS:
        regexp = re.compile(pattern)
        for ch in first:
            cls.yaml_implicit_resolvers.setdefault(ch, []).append((tag, regexp))
    cls.yaml_implicit_resolvers.setdefault("", []).append((_TAG + "null", re.compile(r"^$")))


class _Refused(ConstructorError):
    """A document this reader refuses, though PyYAML would read it (a duplicate key, a limit, a refused form)."""


SHOWN_CHARS = 200
"""The most characters of one value that a message shows (:func:`short_repr`, :func:`cut_message`): a longer value
is cut to its start, and its length is said."""

MAX_MESSAGE_CHARS = 4000
"""The most characters of one message (:func:`cut_message`), once its over-long values are cut."""


def short_repr(value: Any, limit: int = SHOWN_CHARS) -> str:
    """``repr(value)`` as a message shows it: whole up to ``limit`` characters; longer, its start, ``...`` (``limit``
    characters in all) and its length (a string's length in characters): ``'xxxx... (200,000 characters)``. A
    200 kB string given as a config value is not echoed whole in the error that refuses it."""
    text = repr(value)
    if len(text) <= limit:
        return text
    return f"{text[:limit - 3]}... ({len(value) if isinstance(value, str) else len(text):,} characters)"


_short = functools.partial(short_repr, limit=60)  # a key or a number in a YAML error: cut shorter

# a quoted value in a message ('...' or "...", as repr writes it: not the apostrophe of "model's"), or a run of
# characters without a space
_LONG_VALUE = re.compile(r"""(?<![\w'"])('(?:[^'\\\n]|\\.)*'|"(?:[^"\\\n]|\\.)*")(?!\w)|\S+""")


def cut_message(text: str, limit: int = SHOWN_CHARS) -> str:
    """``text`` (an error message) with every value in it longer than ``limit`` characters cut as
    :func:`short_repr` cuts one (a quoted value, or any run of characters without a space: a path, a list written
    without spaces), and the whole cut to :data:`MAX_MESSAGE_CHARS` (its start, and its length said). The one
    place where a message that quotes its input is kept to a readable length (the command line's error line,
    :func:`pneunet_env.config.load_config`'s errors)."""
    text = str(text)
    if len(text) <= limit:
        return text

    def cut(match: re.Match) -> str:
        value = match.group(0)
        if len(value) <= limit:
            return value
        quoted = match.group(1) is not None  # (cut as short_repr cuts: a message cut again is unchanged)
        return f"{value[:limit - 3]}... ({len(value) - 2 if quoted else len(value):,} characters)"

    out = _LONG_VALUE.sub(cut, text)
    if len(out) > MAX_MESSAGE_CHARS:
        out = f"{out[:MAX_MESSAGE_CHARS]}... (the message cut: {len(out):,} characters)"
    return out


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader, with the resolvers and constructors above and the size limits at compose time."""

    yaml_constructors: dict = {}

    def __init__(self, stream: Any) -> None:
        super().__init__(stream)
        self._aliases = 0
        self._depth = 0

    # ---- composing: aliases, depth and expanded size are checked before anything is constructed ---------------
    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            mark = self.peek_event().start_mark
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                raise _Refused(None, None, f"more than {MAX_ALIASES} aliases (an alias bomb?)", mark)
            node = super().compose_node(parent, index)
            if not hasattr(node, "pneunet_size"):
                raise _Refused(None, None, "a recursive alias (a node that contains itself)", mark)
            return node
        mark = self.peek_event().start_mark
        self._depth += 1
        if self._depth > MAX_DEPTH:
            raise _Refused(None, None, f"nested deeper than {MAX_DEPTH} levels", mark)
        try:
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
        if isinstance(node, ScalarNode):
            size = 1 + len(node.value)
        elif isinstance(node, SequenceNode):
            size = 1 + sum(child.pneunet_size for child in node.value)
        else:
            size = 1 + sum(k.pneunet_size + v.pneunet_size for k, v in node.value)
        if size > MAX_EXPANDED_SIZE:
            raise _Refused(None, None, f"its aliases expand it past {MAX_EXPANDED_SIZE:,} characters "
                                   "(an alias bomb?)", mark)
        node.pneunet_size = size
        return node

    # ---- constructing -------------------------------------------------------------------------------------------
    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        if isinstance(node, MappingNode):
            seen: dict[Any, int] = {}
            for key_node, value_node in node.value:
                if key_node.tag == _TAG + "merge":
                    continue
                key = self.construct_object(key_node, deep=deep)
                try:
                    hash(key)
                except TypeError:
                    raise _Refused("while constructing a mapping", node.start_mark,
                                           f"found an unhashable key ({type(key).__name__})",
                                           key_node.start_mark) from None
                line = key_node.start_mark.line + 1
                if key in seen:
                    raise _Refused(None, None, f"duplicate key {_short(key)} (first at line {seen[key]})",
                                           key_node.start_mark)
                seen[key] = line
                if value_node.tag == _AMBIGUOUS_BOOL_TAG:  # named with its key
                    raise _Refused(None, None, f"key {_short(key)}: {_ambiguous_bool(value_node.value)}",
                                   value_node.start_mark)
        return super().construct_mapping(node, deep=deep)


def _construct_int(loader: _Loader, node: Any) -> int:
    text = str(loader.construct_scalar(node)).replace("_", "")
    sign, body = (-1, text[1:]) if text[:1] == "-" else (1, text[1:] if text[:1] == "+" else text)
    try:
        for prefix, base in (("0b", 2), ("0o", 8), ("0x", 16)):
            if body.lower().startswith(prefix):
                return sign * int(body[2:], base)
        if len(body) > 1 and body.startswith("0"):
            raise ValueError("a leading zero")
        return sign * int(body)
    except ValueError as exc:
        raise _Refused(None, None, f"cannot read {_short(text)} as an integer ({exc})", node.start_mark) from None


def _construct_float(loader: _Loader, node: Any) -> float:
    text = str(loader.construct_scalar(node)).replace("_", "")
    low = text.lower()
    if low in (".inf", "+.inf", "-.inf", ".nan", "+.nan", "-.nan"):
        return math.copysign(math.inf, -1.0 if low.startswith("-") else 1.0) if "inf" in low else math.nan
    try:
        return float(text)
    except ValueError:
        raise _Refused(None, None, f"cannot read {_short(text)} as a number", node.start_mark) from None


def _construct_bool(loader: _Loader, node: Any) -> bool:
    text = str(loader.construct_scalar(node))
    try:
        return _BOOL[text.lower()]
    except KeyError:
        raise _Refused(None, None, f"cannot read {_short(text)} as true or false", node.start_mark) from None


def _construct_ambiguous(loader: _Loader, node: Any) -> Any:
    text = loader.construct_scalar(node)
    if ":" in text:
        hint = "YAML 1.1 reads it in base 60, YAML 1.2 as a string): quote it for a string"
    else:
        hint = ("YAML 1.1 reads a leading zero as octal, YAML 1.2 as decimal): write it without the leading zero, "
                "with 0o for octal, or quote it for a string")
    raise _Refused(None, None, f"the number {_short(text)} is ambiguous ({hint}", node.start_mark)


def _ambiguous_bool(text: str) -> str:
    """Why ``yes``/``no``/``on``/``off`` are refused, and what to write instead."""
    meant = "true" if text.lower() in ("yes", "on") else "false"
    return (f"{text!r} is {meant} in YAML 1.1 (PyYAML, rl-zoo3) but a string in YAML 1.2: write true or false "
            f"({meant} for {text!r}), or quote it for a string")


def _construct_ambiguous_bool(loader: _Loader, node: Any) -> Any:
    raise _Refused(None, None, _ambiguous_bool(loader.construct_scalar(node)), node.start_mark)


def _construct_undefined(loader: _Loader, node: Any) -> Any:
    raise _Refused(None, None, f"the tag {node.tag!r} is not read (plain data only: mappings, lists, "
                           "strings, numbers, booleans, null)", node.start_mark)


_add_resolvers(_Loader)
_Loader.yaml_constructors = {
    _TAG + "null": yaml.SafeLoader.construct_yaml_null,
    _TAG + "bool": _construct_bool,
    _TAG + "int": _construct_int,
    _TAG + "float": _construct_float,
    _TAG + "str": yaml.SafeLoader.construct_yaml_str,
    _TAG + "seq": yaml.SafeLoader.construct_yaml_seq,
    _TAG + "map": yaml.SafeLoader.construct_yaml_map,
    _AMBIGUOUS_TAG: _construct_ambiguous,
    _AMBIGUOUS_BOOL_TAG: _construct_ambiguous_bool,
    None: _construct_undefined,
}


class _Dumper(yaml.SafeDumper):
    """PyYAML's safe dumper, quoting every string that :class:`_Loader` would read as something else."""


_add_resolvers(_Dumper)


# ---------------------------------------------------------------------------------------------
# YAML
# ---------------------------------------------------------------------------------------------


def _check_size(data: str | bytes, source: str, limit: int) -> None:
    if not isinstance(data, (str, bytes)):
        raise TypeError(f"{source}: expected text, got {type(data).__name__}")
    # a str's UTF-8 size is at least its length and at most 4 times it: encode it only when that could matter
    size = len(data)
    if isinstance(data, str) and size <= limit < 4 * size:
        size = len(data.encode("utf-8", "surrogatepass"))
    if size > limit:
        raise ValueError(f"{source}: larger than the {limit:,} bytes read")


def _yaml_error(exc: yaml.YAMLError, source: str) -> ValueError:
    problem = getattr(exc, "problem", None) or str(exc)
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    context = getattr(exc, "context", None)
    context_mark = getattr(exc, "context_mark", None)
    if context and context_mark is not None and mark is not None and context_mark.line != mark.line:
        context += f" (line {context_mark.line + 1})"
    where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
    text = " ".join(f"{context + ': ' if context else ''}{problem}".split())
    if isinstance(exc, _Refused):
        return ValueError(f"{source}{where.replace(' (', ', ').rstrip(')')}: {text}")
    return ValueError(f"cannot read {source}: not valid YAML{where}: {text}")


def load_yaml(text: str | bytes, source: str = "<string>") -> Any:
    """The value of one YAML document (``None`` if empty), by the rules of this module.

    Args:
        text: the document (``bytes`` are decoded as UTF-8, or UTF-16 with a byte-order mark).
        source: what it is, for messages: a file's path, ``--set 'KEY=VALUE'``.

    Raises:
        ValueError: naming ``source`` (and the line, where there is one): a syntax error, a duplicate key, a refused
            tag or number form, or a document past the limits.
        TypeError: ``text`` is neither ``str`` nor ``bytes``.
    """
    _check_size(text, source, MAX_INPUT_BYTES)
    loader = None
    try:
        loader = _Loader(text)  # its reader decodes bytes and refuses control characters here
        return loader.get_single_data()
    except yaml.YAMLError as exc:
        raise _yaml_error(exc, source) from None
    except RecursionError:  # pragma: no cover - MAX_DEPTH keeps the composer well inside the stack
        raise ValueError(f"{source}: nested too deeply") from None
    finally:
        if loader is not None:
            loader.dispose()


def parse_value(text: str, source: str = "--set") -> Any:
    """One ``--set KEY=VALUE`` value, read exactly as the same text is read in a YAML file (:func:`load_yaml`):
    ``5e1`` is 50.0, ``[30, 1000]`` a list, ``true`` a boolean, ``null`` (or nothing) ``None``."""
    return load_yaml(text, source)


# ---------------------------------------------------------------------------------------------
# Files: what may be opened to read
# ---------------------------------------------------------------------------------------------

_NOT_FILES = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (a named pipe: reading it would wait for a writer)"),
              (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def file_kind(mode: int) -> str | None:
    """What a file of ``st_mode`` ``mode`` is, in words, where it is not a regular file (``"a folder"``, ``"a FIFO
    (...)"``, ``"a character device"``, ...); ``None`` for a regular file."""
    return next((words for test, words in _NOT_FILES if test(mode)), None)


def _limit(folder: str, name: str, default: int) -> int:
    try:
        return int(os.pathconf(folder, name))
    except (AttributeError, OSError, ValueError):  # no pathconf (Windows), or not known there
        return default


def path_too_long(path: str | os.PathLike) -> str | None:
    """Why ``path`` is too long for the file system, in words (a name in it over ``NAME_MAX`` bytes, usually 255, or
    the whole over ``PATH_MAX``, usually 4,096), or ``None``. Checked on the text: the file system says
    ``ENAMETOOLONG`` only once it reaches the long name, and says "no such file" first where a folder above it is
    missing."""
    text = os.fsdecode(os.fspath(path))
    raw = os.fsencode(text)
    folder = os.path.dirname(os.path.abspath(text)) or os.sep
    while not os.path.isdir(folder) and os.path.dirname(folder) != folder:  # (isdir: False for a too-long one)
        folder = os.path.dirname(folder)
    path_max, name_max = _limit(folder, "PC_PATH_MAX", 4096), _limit(folder, "PC_NAME_MAX", 255)
    if os.sep == "\\":  # Windows: either slash
        raw = raw.replace(b"\\", b"/")
    longest = max((len(part) for part in raw.split(b"/")), default=0)
    if longest > name_max:
        return f"a name in it is {longest:,} bytes long; the file system takes at most {name_max:,}"
    if len(raw) >= path_max:
        return f"it is {len(raw):,} bytes long; the file system takes at most {path_max - 1:,}"
    return None


def check_input_file(path: str | os.PathLike, source: str) -> None:
    """Refuse, before anything opens it, a path that cannot be read as a file: ``ValueError`` naming ``source`` for a
    path too long for the file system (:func:`path_too_long`), or one that exists and is not a regular file (a
    folder, a FIFO, whose opening would wait for a writer for ever, a device such as ``/dev/zero``, endless, or a
    socket: :func:`file_kind`). A missing file passes (its reader says so, or finds it by another name)."""
    why = path_too_long(path)
    if why is not None:
        raise ValueError(f"cannot read {source}: the path is too long ({why})")
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):  # missing, unreadable, a NUL in the name: the reader's open names it
        return
    kind = file_kind(mode)
    if kind is not None:
        raise ValueError(f"cannot read {source}: it is {kind}, not a regular file")


def _read_bytes(path: str | os.PathLike, what: str, limit: int) -> tuple[bytes, str]:
    source = f"{what} {short_repr(os.fsdecode(os.fspath(path)))}"
    check_input_file(path, source)  # a FIFO, a device or a too-long path: refused by name, before the open
    try:
        # not blocking: a FIFO put there since the check is not waited on (its kind is refused below)
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    except OSError as exc:
        raise ValueError(f"cannot read {source}: {exc.strerror or exc}") from None
    with os.fdopen(fd, "rb") as fh:
        try:
            kind = file_kind(os.fstat(fd).st_mode)
            if kind is not None:
                raise ValueError(f"cannot read {source}: it is {kind}, not a regular file")
            if hasattr(os, "O_NONBLOCK"):
                os.set_blocking(fd, True)
            data = fh.read(limit + 1)
        except OSError as exc:
            raise ValueError(f"cannot read {source}: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise ValueError(f"{source}: larger than the {limit:,} bytes read")
    return data, source


def load_yaml_file(path: str | os.PathLike, what: str = "YAML file") -> Any:
    """The value of the YAML file ``path`` (:func:`load_yaml`); messages name it as ``what 'path'``.

    Raises:
        ValueError: the file cannot be read (named), or as :func:`load_yaml`.
    """
    data, source = _read_bytes(path, what, MAX_INPUT_BYTES)
    return load_yaml(data, source)


def dump_yaml(data: Any, **kwargs: Any) -> str:
    """YAML text of plain ``data`` that :func:`load_yaml` reads back to equal values (block style, key order kept
    unless ``sort_keys=True``; other keyword arguments go to :func:`yaml.dump`)."""
    kwargs.setdefault("sort_keys", False)
    return yaml.dump(data, Dumper=_Dumper, **kwargs)


# ---------------------------------------------------------------------------------------------
# JSON
# ---------------------------------------------------------------------------------------------


def _line_of(text: str, index: int) -> int:
    return text.count("\n", 0, index) + 1


class _JSONDecoder(json.JSONDecoder):
    """The standard decoder, with Python's scanner so that each object knows where it starts: a duplicate key is
    refused naming the line of its object."""

    def __init__(self, source: str) -> None:
        super().__init__()
        self.source = source
        self.parse_object = self._parse_object
        self.scan_once = json.scanner.py_make_scanner(self)

    def _parse_object(self, s_and_end, strict, scan_once, object_hook, object_pairs_hook, memo=None):
        text, start = s_and_end
        pairs, end = json.decoder.JSONObject(s_and_end, strict, scan_once, None, list, memo)
        out: dict[str, Any] = {}
        for key, value in pairs:
            if key in out:
                raise ValueError(f"{self.source}: duplicate key {key!r} in the object that starts at line "
                                 f"{_line_of(text, start - 1)}")
            out[key] = value
        return out, end


def load_json(text: str | bytes, source: str = "<string>") -> Any:
    """The value of a JSON document; duplicate keys, a syntax error or a document over :data:`MAX_JSON_BYTES` raise
    ``ValueError`` naming ``source`` (and the line). ``NaN`` and ``Infinity`` are read, as Python's ``json`` does."""
    _check_size(text, source, MAX_JSON_BYTES)
    if isinstance(text, bytes):
        try:
            text = text.decode(json.detect_encoding(text), "surrogatepass")
        except UnicodeDecodeError as exc:
            raise ValueError(f"cannot read {source}: not JSON (not UTF-8/16/32 text: {exc.reason})") from None
    if text.startswith("\ufeff"):
        text = text[1:]
    try:
        return _JSONDecoder(source).decode(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"cannot read {source}: not JSON (line {exc.lineno}, column {exc.colno}): "
                         f"{exc.msg}") from None
    except RecursionError:
        raise ValueError(f"cannot read {source}: not JSON: nested too deeply") from None


def load_json_file(path: str | os.PathLike, what: str = "JSON file") -> Any:
    """The value of the JSON file ``path`` (:func:`load_json`); messages name it as ``what 'path'``."""
    data, source = _read_bytes(path, what, MAX_JSON_BYTES)
    return load_json(data, source)
