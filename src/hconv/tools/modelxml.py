"""Model files as untrusted XML: parsed with the standard library's expat, with line numbers, and
with MuJoCo's ``<include>`` resolved. Nothing here reaches the network or runs what a file says.

What a model file cannot do to hconv (each refusal is one :class:`~hconv.errors.InputError` that
names the file, the line and the fix):

* declare entities: a DOCTYPE with an internal subset (``<!DOCTYPE x [ ... ]>``) or any
  ``<!ENTITY`` is refused before parsing, so neither the "billion laughs" expansion nor an external
  entity (``SYSTEM "file:///etc/passwd"``) is ever seen by the parser. The parser refuses them
  again if an encoding hid them from that scan, never reads a DTD, and refuses an entity
  reference that a DTD it did not read might define.
* pull in other files, except MJCF's ``<include file=...>``: relative to the main model's folder,
  as MuJoCo resolves it (an included file's own include, when not found there, beside that file,
  where MuJoCo 4.0 looks next; a backslash read as ``/``, as MuJoCo 4.0 reads it on Linux too),
  and only inside that folder, or inside a root folder the user names (``--root``; metaworld's
  models include ``../scene/...``): a ``..`` or a symbolic link that leads beyond it is refused;
  each file at most once (as MuJoCo), which also ends cycles. XInclude is not processed and is
  refused, since ignoring it would drop bodies.
* exhaust memory or time: a model larger than :data:`MAX_BYTES`, with all it includes, is refused;
  so is one of more than :data:`MAX_ELEMENTS` elements or nested deeper than :data:`MAX_DEPTH`,
  and one whose body names (SDF's ``model::link``, MJCF's path of an unnamed body), which grow
  with the nesting, would add up to more than :func:`Budget.names_allowed`. Within those limits a
  model takes memory and time linear in its size (README, "A robot model's inertias"). Only
  regular files are read (not a FIFO or a device, which could block or never end), opened without
  blocking. Trees are walked without recursion, so a deeply nested file cannot overflow Python's
  stack.
* flood the terminal: a message quotes at most :data:`QUOTED` characters of any value from the
  file (:func:`quote`), so a 60 MB attribute is refused in one short line.
"""

from __future__ import annotations

import errno
import itertools
import os
import re
import shlex
import stat
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

from hconv import errors
from hconv.errors import InputError, on_command_line, option

#: The largest model file hconv reads [bytes]. Real URDF, SDF and MJCF files are kilobytes to a
#: few megabytes (meshes live in files of their own); a file beyond this is not a model.
MAX_BYTES = 64 << 20
#: The most elements a model, with all it includes, may have. A robot has tens to thousands; a
#: large simulated world some ten thousand. Each element costs memory (a Node, its attributes;
#: a body's numbers), so this is what bounds a model of tiny elements (``<a/>``, 4 bytes each);
#: the figures are in docs/measurements.md.
MAX_ELEMENTS = 1_000_000
#: The deepest nesting of elements a file may have. tinyxml2, which MuJoCo and libsdformat parse
#: with, stops at 100 or 500 levels (by version); a real model nests tens deep.
MAX_DEPTH = 500
#: The most characters of a value from a file that a message quotes.
QUOTED = 80

_XINCLUDE = "http://www.w3.org/2001/XInclude"
_EXTERNAL_DTD = (
    "has a DOCTYPE that names an external DTD, which hconv never reads (so any entity it defines "
    "would be lost): remove the DOCTYPE"
)
_TOKEN = re.compile(r"\S+")
# One way to match each number: ``\d+\.?\d*`` had as many as there are digits, and took minutes
# to refuse a long run of digits that ends in a letter.
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")


def clip(text: str, limit: int = QUOTED) -> str:
    """``text`` whole if it has at most ``limit`` characters, else its start and its end either
    side of "…" in ``limit`` characters: a value from a file can be megabytes long."""
    return errors.clip(text, limit)


def quote(value: str) -> str:
    """``value`` as a message quotes it: in quotes, escaped (so that it stays on one line), and
    :func:`clip`-ped to :data:`QUOTED` characters. Every message that quotes a value from a model
    file goes through here."""
    return repr(clip(value))


class Budget:
    """What a model, with all it includes, has used of hconv's limits (the module's docstring).

    One per model: :func:`read` adds each file's bytes and elements, and the readers of
    :mod:`hconv.tools.models` each body name they make."""

    def __init__(self, shown: str) -> None:
        self.shown = shown  #: the main model, as the user named it
        self.bytes = 0
        self.elements = 0
        self.name_chars = 0

    def names_allowed(self) -> int:
        """The characters that the names of a model's bodies may add up to: four times the
        bytes read, and a mebibyte. Names that the file spells out fit many times over; only
        names made by nesting (``a::b::c::link``) can outgrow the file, by its depth."""
        return 4 * self.bytes + (1 << 20)

    def add_bytes(self, n: int, shown: str) -> None:
        self.bytes += n
        if self.bytes > MAX_BYTES:
            raise InputError(
                f"{shown}: brings the model {self.shown} with its includes to {self.bytes / (1 << 20):.0f} MiB, "
                f"larger than any model hconv reads ({MAX_BYTES >> 20} MiB); is it a model (URDF, SDF or MJCF)?"
            )

    def name(self, name: str, node: Node) -> str:
        """``name``, counted against :meth:`names_allowed`; InputError at ``node`` beyond it."""
        self.name_chars += len(name)
        if self.name_chars > self.names_allowed():
            raise error(
                node,
                f"gets the name {quote(name)} ({len(name):,} characters), which brings the body names "
                f"hconv makes from the nesting to more than {self.names_allowed():,} characters (four "
                "times the model's size, and 1 MiB)",
                "nest models or unnamed bodies less deeply, or name the bodies",
            )
        return name


@dataclass(slots=True)
class Node:
    """One XML element: its tag, attributes, child elements, own text, and where it stands."""

    tag: str
    attrib: dict[str, str]
    file: str  #: the file as the user named it (an included file: as the include named it)
    line: int
    children: list[Node] = field(default_factory=list)
    text: str = ""

    @property
    def where(self) -> str:
        """``arm.urdf, line 12, <inertia>``: for messages."""
        return f"{self.file}, line {self.line}, <{clip(self.tag)}>"

    def find(self, tag: str) -> Node | None:
        """The one child ``tag``, or None; InputError when there are several."""
        found = [c for c in self.children if c.tag == tag]
        if len(found) > 1:
            raise error(found[1], f"is the second <{tag}> in <{clip(self.tag)}>", f"keep one <{tag}>")
        return found[0] if found else None

    def findall(self, tag: str) -> list[Node]:
        return [c for c in self.children if c.tag == tag]

    def numbers(self, name: str, counts: tuple[int, ...], default: str | None = None) -> list[float] | None:
        """Attribute ``name`` as whitespace-separated finite numbers, ``counts`` of them (or the
        text of the element when ``name`` is ``""``); ``default`` when absent, None if that is None."""
        raw = self.text if name == "" else self.attrib.get(name)
        if raw is None or (name == "" and (not raw or raw.isspace()) and default is not None):
            raw = default
        if raw is None:
            return None
        what = "its text" if name == "" else f"attribute {name}"
        return parse_numbers(raw, counts, self, what)

    def required(self, name: str, counts: tuple[int, ...], fix: str) -> list[float]:
        """Like :meth:`numbers`, but InputError naming ``fix`` when the attribute is absent."""
        values = self.numbers(name, counts)
        if values is None:
            raise error(self, f"has no attribute {name}", fix)
        return values


def error(node: Node, problem: str, fix: str) -> InputError:
    """One line: where, what is wrong, and how to fix it."""
    return InputError(f"{node.where} {problem}; {fix}")


def walk(root: Node) -> list[Node]:
    """Every element under ``root``, in document order, without recursion."""
    out, stack = [], [root]
    while stack:
        n = stack.pop()
        out.append(n)
        stack.extend(reversed(n.children))
    return out


def required_name(node: Node, what: str) -> str:
    """The element's ``name``; InputError asking for one, ``what`` being what it names."""
    name = node.attrib.get("name", "").strip()
    if not name:
        raise error(node, "has no name", f'name the {what}: <{node.tag} name="...">')
    return name


def flag(node: Node, name: str) -> bool:
    """Boolean attribute ``name`` (true, false, 1 or 0; false when absent)."""
    v = node.attrib.get(name, "false").strip().lower()
    if v not in ("true", "false", "1", "0"):
        raise error(node, f"has {name}={quote(v)}", f'write {name}="true" or {name}="false"')
    return v in ("true", "1")


def parse_numbers(raw: str, counts: tuple[int, ...], node: Node, what: str) -> list[float]:
    """``raw`` as ``counts`` finite numbers (decimal notation only: no nan, inf, hex or 1_000).

    A value of more numbers than it takes is refused after reading one more than it takes, so a
    60 MB attribute costs a scan, not a list of millions of numbers."""
    most = max(counts)
    tokens = [m.group() for m in itertools.islice(_TOKEN.finditer(raw), most + 1)]  # no copy of the rest
    for t in tokens:
        if not _NUMBER.fullmatch(t):
            hint = (
                "it is a xacro expression: run xacro on the file first (xacro model.urdf.xacro > model.urdf)"
                if "$" in raw
                else "write a decimal number such as 0.25 or 1e-3"
            )
            raise error(node, f"{what} holds {quote(t)}, which is not a number", hint)
    want = " or ".join(str(c) for c in counts)
    if len(tokens) > most:
        raise error(
            node,
            f"{what} holds more than {most} numbers ({quote(clip(raw).strip())}), but takes {want}",
            "give " + want,
        )
    values = [float(t) for t in tokens]
    big = next((t for t, v in zip(tokens, values) if not abs(v) < float("inf")), None)
    if big is not None:
        raise error(node, f"{what} holds {clip(big)}, beyond the range of a float", "check the value")
    if len(values) not in counts:
        raise error(
            node, f"{what} holds {len(values)} numbers ({quote(clip(raw).strip())}), but takes {want}", "give " + want
        )
    return values


def _line_of(data: bytes, at: int) -> int:
    return data.count(b"\n", 0, at) + 1


def _refuse_declarations(data: bytes, shown: str) -> None:
    """Refuse entity declarations before the parser sees them (see the module's docstring)."""
    at = data.find(b"<!ENTITY")
    if at >= 0:
        raise InputError(
            f"{shown}, line {_line_of(data, at)}: declares an entity (<!ENTITY ...>); hconv reads no "
            "entity declarations, which can expand without bound or read other files: remove the DOCTYPE "
            "and write the values out"
        )
    at = data.find(b"<!DOCTYPE")
    if at >= 0:
        end = data.find(b">", at)
        decl = data[at : end if end >= 0 else len(data)]
        if b"[" in decl:
            raise InputError(
                f"{shown}, line {_line_of(data, at)}: has a DOCTYPE with declarations ([ ... ]); hconv reads "
                "no DTD declarations: remove the DOCTYPE"
            )
        if b"SYSTEM" in decl or b"PUBLIC" in decl:
            raise InputError(f"{shown}, line {_line_of(data, at)}: {_EXTERNAL_DTD}")


class _RefusedError(Exception):
    """Raised inside an expat handler; carries the message (the line is the parser's)."""


def parse_bytes(data: bytes, shown: str, budget: Budget | None = None) -> Node:
    """Parse ``data`` into a tree of :class:`Node`; InputError naming ``shown`` and the line.

    Two slips that other model readers (TinyXML, in urdfdom and Bullet) let pass, and that change
    nothing in the content, are forgiven: blank lines before the XML declaration, and NUL bytes
    after the last element (a C string's terminator written out). Lines keep their numbers.
    ``budget``: the model's, when ``data`` is one of its files (one of its own otherwise).
    """
    budget = budget or Budget(shown)
    _refuse_declarations(data, shown)
    head = data.lstrip(b" \t\r\n")
    closes = head.find(b"?>")
    if head is not data and head.startswith(b"<?xml") and closes >= 0:
        # the declaration first, as expat wants it, and the blank lines after it: lines keep their numbers
        data = head[: closes + 2] + data[: len(data) - len(head)] + head[closes + 2 :]
    data = data.rstrip(b"\x00")
    p = expat.ParserCreate()
    p.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)  # never read an external DTD
    stack: list[Node] = []
    roots: list[Node] = []
    texts: list[list[str]] = []

    def start(tag: str, attrib: dict[str, str]) -> None:
        # xacro's own <xacro:include> is a macro, not XInclude: the URDF reader refuses every xacro
        # element with the fix that works for it (run xacro first); pasting content in would not
        xinclude = tag.endswith(":include") and not tag.startswith("xacro:")
        if xinclude or any(k.startswith("xmlns") and v == _XINCLUDE for k, v in attrib.items()):
            raise _RefusedError(
                f"<{clip(tag)}> uses XInclude, which hconv does not follow; paste the included content in"
            )
        if len(stack) >= MAX_DEPTH:
            raise _RefusedError(
                f"nests elements more than {MAX_DEPTH} deep, deeper than any model (MuJoCo and libsdformat "
                "refuse it too); is it a model?"
            )
        budget.elements += 1
        if budget.elements > MAX_ELEMENTS:
            raise _RefusedError(
                f"brings the model {budget.shown} to more than {MAX_ELEMENTS:,} elements, more than any model "
                "hconv reads; is it a model?"
            )
        node = Node(tag, attrib, shown, p.CurrentLineNumber)  # expat gives each element a dict of its own
        (stack[-1].children if stack else roots).append(node)
        stack.append(node)
        texts.append([])

    def end(tag: str) -> None:
        node = stack.pop()
        node.text = "".join(texts.pop())

    def chars(s: str) -> None:
        if texts:
            texts[-1].append(s)

    def doctype(name: str, sysid: str | None, pubid: str | None, internal: int) -> None:
        if internal:
            raise _RefusedError("has a DOCTYPE with declarations ([ ... ]); hconv reads no DTD declarations: remove it")
        if sysid or pubid:
            raise _RefusedError(_EXTERNAL_DTD)

    def entity(*args: object) -> None:
        raise _RefusedError("declares an entity; hconv reads no entity declarations: remove the DOCTYPE")

    def external(*args: object) -> int:
        raise _RefusedError("refers to an external entity; hconv reads no other files this way: write the values out")

    def skipped(name: str, is_parameter: int) -> None:
        raise _RefusedError(f"uses the entity &{clip(name)}; that no part of the file defines; write the value out")

    p.StartElementHandler = start
    p.EndElementHandler = end
    p.CharacterDataHandler = chars
    p.StartDoctypeDeclHandler = doctype
    p.EntityDeclHandler = entity
    p.UnparsedEntityDeclHandler = entity
    p.ExternalEntityRefHandler = external
    p.SkippedEntityHandler = skipped
    try:
        p.Parse(data, True)
    except _RefusedError as exc:
        raise InputError(f"{shown}, line {p.CurrentLineNumber}: {exc}") from None
    except expat.ExpatError as exc:
        why = expat.ErrorString(exc.code) or "unknown"
        why = why.removeprefix("not well-formed ").strip("()")
        raise InputError(
            f"{shown}, line {exc.lineno}, column {exc.offset + 1}: not well-formed XML ({why}); fix the XML there"
        ) from None
    if not roots:
        raise InputError(f"{shown}: holds no XML element; give a URDF, SDF or MJCF model")
    return roots[0]


def read(path: Path, shown: str, budget: Budget | None = None) -> Node:
    """Parse the model file at ``path`` (named ``shown`` in messages); InputError with the fix.
    ``budget``: the model's, when the file is one it includes."""
    budget = budget or Budget(shown)
    try:
        st = os.stat(path)
    except OSError as exc:
        raise InputError(f"{shown}: cannot read it ({exc.strerror or exc}); check the path") from None
    _check_kind(st, shown)
    try:
        # without blocking: a file swapped for a FIFO after the stat above must not hang the open
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        raise InputError(f"{shown}: cannot read it ({exc.strerror or exc}); check its permissions") from None
    try:
        with open(fd, "rb") as f:
            st = os.fstat(fd)
            _check_kind(st, shown)  # what was opened, which is what is read
            data = f.read(st.st_size + 1)  # its size, and a byte more to see whether it grew since
            if len(data) > st.st_size:  # it did: on to the limit, beyond which add_bytes refuses it
                data += f.read(MAX_BYTES + 1 - len(data))
    except OSError as exc:
        raise InputError(f"{shown}: cannot read it ({exc.strerror or exc}); check its permissions") from None
    budget.add_bytes(len(data), shown)
    if not data.strip():
        raise InputError(f"{shown}: is empty; give a URDF, SDF or MJCF model")
    other = _other_kind(data)
    if other:  # expat would say "not well-formed (invalid token)" of its first bytes
        raise InputError(f"{shown}: is {other}, not a model file; give a URDF, SDF or MJCF model (XML text)")
    return parse_bytes(data, shown, budget)


def _other_kind(data: bytes) -> str | None:
    """What a file whose first bytes are no XML is, by its magic number (a spreadsheet, an
    archive): None for any other file, which the XML parser then reads or refuses."""
    if data.startswith(b"PK\x03\x04"):
        head = data[:4096]
        if b"[Content_Types].xml" in head or b"xl/" in head:
            return "an Excel workbook (.xlsx, a zip of spreadsheet parts)"
        if b"opendocument.spreadsheet" in head:
            return "an OpenDocument spreadsheet (.ods, a zip)"
        return "a zip archive (unzip it and give the model file inside)"
    for magic, what in _MAGIC:
        if data.startswith(magic):
            return what
    return None


#: The first bytes of other files given as a model, and what a message calls them.
_MAGIC = (
    (b"\x1f\x8b", "gzip-compressed (decompress it first: gzip -dc)"),
    (b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1", "an Excel 97-2003 workbook (.xls)"),
    (b"PAR1", "a Parquet file"),
)


def _check_kind(st: os.stat_result, shown: str) -> None:
    """InputError unless ``st`` is a regular file within :data:`MAX_BYTES`."""
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{shown}: is a directory; give the model file inside it")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{shown}: is not a regular file (a pipe or a device); save the model to a file first")
    if st.st_size > MAX_BYTES:
        raise InputError(
            f"{shown}: is {st.st_size / (1 << 20):.0f} MiB, larger than any model file hconv reads "
            f"({MAX_BYTES >> 20} MiB); is it a model (URDF, SDF or MJCF)?"
        )


def expand_includes(
    root: Node, model: Path, shown: str, budget: Budget | None = None, include_root: Path | None = None
) -> None:
    """Replace every ``<include file=...>`` under ``root`` (read from ``model``) by the children of
    the included file's top element, as MuJoCo does: paths relative to the main model's folder,
    each file at most once. Walked with a work list, not recursion. ``budget``: the model's, which
    each included file adds to. ``include_root``: the folder (holding the model's) within which
    includes may go; the model's folder when None."""
    budget = budget or Budget(shown)
    folder = model.resolve().parent
    allowed = include_root.resolve() if include_root is not None else folder
    seen = {model.resolve(): shown}
    # the files an element is read from, innermost first: (file, (its includer, (...))), one
    # pair per include, so that a chain of includes is not a tuple copied at each
    work: list[tuple[Node, _Chain]] = [(root, (model.resolve(), None))]
    while work:
        node, chain = work.pop()
        kept = []
        # the children, each include replaced in place by the included file's: iterators on a
        # stack, not insertions into a list, which took time quadratic in the includes
        pending: list[tuple[Iterator[Node], _Chain]] = [(iter(node.children), chain)]
        while pending:
            children, ch = pending[-1]
            child = next(children, None)
            if child is None:
                pending.pop()
                continue
            if child.tag != "include":
                kept.append(child)
                work.append((child, ch))
                continue
            name = child.attrib.get("file")
            if not name or not name.strip():
                raise error(child, "has no attribute file", 'name the file to include: <include file="parts.xml"/>')
            # MuJoCo (4.0) looks beside the main model first, then beside the including file
            base, beside = folder, ch[0].parent
            if beside != folder and not _exists(folder / _slashed(name)) and _exists(beside / _slashed(name)):
                base = beside
            target = _include_target(child, name, base, allowed, include_root is not None)
            if target in seen:  # read before: a cycle when it is one of the files this include is in
                files: list[Path] = []
                link: _Chain | None = ch
                while link is not None and not (files and files[-1] == target):
                    files.append(link[0])
                    link = link[1]
                if files[-1] == target:
                    cycle = " → ".join([seen[c] for c in reversed(files)] + [name])
                    raise error(
                        child,
                        f"includes {quote(name)} again inside itself ({clip(cycle)}): a cycle",
                        "remove the include",
                    )
                raise error(
                    child,
                    f"includes {quote(name)}, which {quote(seen[target])} already brought in",
                    "include each file once (MuJoCo refuses it too)",
                )
            seen[target] = name
            _check_included(child, name, target, shown)
            sub = read(target, name, budget)
            pending.append((iter(sub.children), (target, ch)))
        node.children = kept


_Chain = tuple[Path, "_Chain | None"]


def _check_included(node: Node, name: str, target: Path, shown: str) -> None:
    """InputError naming the including file and line when the included file cannot be read:
    read() alone would name only the included file, and the user could not tell which include
    (of several, perhaps in an included file) to fix."""
    # where the user looks for it: beside the main model, as they named that
    # (the folder is the user's own path, shown whole; only what the file wrote is clipped)
    expected = os.path.join(os.path.dirname(shown), _slashed(name))
    # a Windows path: say how it was read, so that "not found" is not blamed on the folder alone
    slash = ", each backslash read as /, as MuJoCo reads it" if "\\" in name else ""
    at = f" ({os.path.join(os.path.dirname(shown), clip(_slashed(name)))}{slash})" if expected != name else ""
    try:
        st = os.stat(target)
    except OSError as exc:
        raise error(
            node,
            f"names {quote(name)}{at}, which cannot be read: {exc.strerror or exc}",
            "includes are relative to the main model's folder, as in MuJoCo: check the path",
        ) from None
    if stat.S_ISDIR(st.st_mode):
        raise error(node, f"names {quote(name)}{at}, which is a directory", "name the model file inside it")
    if not stat.S_ISREG(st.st_mode):
        raise error(
            node,
            f"names {quote(name)}{at}, which is not a regular file (a pipe or a device)",
            "include a file that holds the MJCF",
        )
    try:
        os.close(os.open(target, os.O_RDONLY | os.O_NONBLOCK))
    except OSError as exc:
        raise error(
            node, f"names {quote(name)}{at}, which cannot be read: {exc.strerror or exc}", "check its permissions"
        ) from None


def _pasteable(folder: Path) -> str:
    """``folder`` as the reader pastes it: quoted for the shell on the command line (a space in
    it must not split the option), as it is for Python, where :func:`option` quotes it."""
    return shlex.quote(str(folder)) if on_command_line() else str(folder)


def _exists(path: Path) -> bool:
    """Whether ``path`` leads to something (False for a link loop or a name the system refuses)."""
    try:
        return os.path.exists(path)
    except (OSError, ValueError):
        return False


def _slashed(name: str) -> str:
    """``name`` as MuJoCo opens it: a Windows backslash is a folder separator, on Linux too
    (MuJoCo 4.0 on Linux opens ``assets\\a.xml`` as ``assets/a.xml``)."""
    return name.replace("\\", "/")


def _include_target(node: Node, name: str, folder: Path, allowed: Path, named_root: bool) -> Path:
    """The file ``name`` (in an include at ``node``) names, relative to the model's ``folder``;
    InputError unless it lies within ``allowed`` (``named_root``: the user named that folder)."""
    if "://" in name or name.startswith(("http:", "https:", "file:")):
        raise error(
            node, f"names {quote(name)}, which is not a file path", "hconv reads no URLs: give a path to a file"
        )
    try:
        target = (folder / _slashed(name)).resolve()
    except RuntimeError:  # Python 3.10 to 3.12: "Symlink loop from ..."; a later one raises OSError(ELOOP)
        raise _loop(node, name, folder) from None
    except (OSError, ValueError) as exc:
        if isinstance(exc, OSError) and exc.errno == errno.ELOOP:
            raise _loop(node, name, folder) from None
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise error(
            node, f"names {quote(name)}, which cannot be followed: {clip(why)}", "name a file in the model's folder"
        ) from None
    if allowed != target and allowed not in target.parents:
        # where the path leads, when a symbolic link (not the name itself) took it out
        lexical = Path(os.path.normpath(folder / _slashed(name)))
        # paths from the file system, not values from the model: bounded by PATH_MAX, and only
        # of use whole (a clipped one cannot be found), so quoted unclipped
        leads = f" (a symbolic link to {str(target)!r})" if lexical != target else ""
        where = f"the root folder {str(allowed)!r} ({option('root')})" if named_root else "the model's folder"
        if not named_root:
            where += f" {str(allowed)!r}"
        common = Path(os.path.commonpath([allowed, target]))
        fix = (
            f"MuJoCo reads it; give {option('root', _pasteable(common))} to let includes come from within that folder"
            if common != Path(common.anchor)
            else "copy the file into the model's folder"
        )
        raise error(node, f"names {quote(name)}{leads}, outside {where}", fix)
    return target


def _loop(node: Node, name: str, folder: Path) -> InputError:
    """The include names a symbolic link that leads, through links, back to itself."""
    return error(
        node,
        f"names {quote(name)} ({clip(str(folder / name))}), a symbolic link that leads back to itself (a loop)",
        "point the link at the file to include, or name that file",
    )
