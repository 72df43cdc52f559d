"""YAML documents decoded to JSON, in a child process (``python -m``).

YAML parsers are slow in Python and can be driven into super-linear time or a crash by a
small document (deep nesting recurses in libyaml's composer); the API therefore never parses
YAML on its own interpreter. With ``--serve`` the child decodes documents one after another
(:mod:`pickstop.runtime.yaml_decoders` keeps it warm and kills it when one outlasts its
time): each message on stdin is an 8-byte big-endian length and the document as UTF-8, each
answer on stdout the same framing around one JSON object, ``{"doc": ...}`` or
``{"error": "..."}``. Without it, the child decodes the whole of stdin and writes one answer
unframed. Only what JSON can say is accepted: null, booleans,
numbers, strings, lists and string-keyed mappings; dates stay strings, and explicit tags of
other types (``!!binary``, ``!!set``, ``!!timestamp``, ``!!omap``...), aliases and integers
of more than 4,300 digits are refused with the line and column.

This module imports nothing of PickStop, so the child starts in the time Python and PyYAML
take to load.
"""

from __future__ import annotations

import json
import os
import struct
import sys
from typing import Any

import yaml
from yaml.constructor import ConstructorError, SafeConstructor
from yaml.resolver import Resolver

CORE = "tag:yaml.org,2002:"
#: The YAML types JSON has: everything else is refused.
JSON_TAGS = tuple(CORE + t for t in ("null", "bool", "int", "float", "str", "seq", "map"))
MEMORY = 512 * 2**20  # [bytes] the child's address space
MAX_INT_BITS = 14_000  # about 4,200 decimal digits: what the JSON decoder reads too
MAX_DEPTH = 128  # nesting of lists and mappings (libyaml's composer recurses on it)


class _Resolver(Resolver):
    """The YAML 1.1 implicit types but timestamps: ``2024-01-01`` is the string it reads as."""


_Resolver.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag != CORE + "timestamp"]
    for first, resolvers in Resolver.yaml_implicit_resolvers.items()
}


class _Constructor(SafeConstructor):
    """The safe constructor restricted to JSON's types, without aliases."""

    def construct_object(self, node: Any, deep: bool = False) -> Any:
        if node in self.constructed_objects or node in self.recursive_objects:
            raise ConstructorError(None, None, "aliases (*name) are not accepted",
                                   node.start_mark)  # fmt: skip
        return super().construct_object(node, deep)

    def construct_yaml_int(self, node: Any) -> int:
        try:
            value = int(super().construct_yaml_int(node))
        except ValueError:
            value = None
        if value is None or value.bit_length() > MAX_INT_BITS:
            digits = sum(c.isalnum() for c in str(node.value))
            raise ConstructorError(None, None, f"an integer of {digits} digits, more than any "
                                   "field accepts", node.start_mark)  # fmt: skip
        return value

    def construct_mapping(self, node: Any, deep: bool = False) -> dict[Any, Any]:
        for key, _ in node.value:
            if key.tag != CORE + "str" and key.tag != CORE + "merge":
                raise ConstructorError(None, None, "mapping keys must be strings (quote "
                                       f"{key.value!r})", key.start_mark)  # fmt: skip
        return super().construct_mapping(node, deep)

    def refuse(self, node: Any) -> Any:
        tag = str(node.tag).replace(CORE, "!!")
        raise ConstructorError(None, None, f"the tag {tag} is not accepted (JSON types "
                               "only: null, booleans, numbers, strings, lists, mappings)",
                               node.start_mark)  # fmt: skip


_Constructor.yaml_constructors = {
    **{t: SafeConstructor.yaml_constructors[t] for t in JSON_TAGS},
    CORE + "int": _Constructor.construct_yaml_int,
    None: _Constructor.refuse,
}

if yaml.__with_libyaml__:
    from yaml.cyaml import CParser as Events

    class _Loader(Events, _Constructor, _Resolver):
        def __init__(self, stream: str) -> None:
            Events.__init__(self, stream)
            _Constructor.__init__(self)
            _Resolver.__init__(self)

else:  # pragma: no cover - PyYAML without libyaml
    from yaml.composer import Composer
    from yaml.parser import Parser
    from yaml.reader import Reader
    from yaml.scanner import Scanner

    class Events(Reader, Scanner, Parser):  # type: ignore[no-redef]
        def __init__(self, stream: str) -> None:
            Reader.__init__(self, stream)
            Scanner.__init__(self)
            Parser.__init__(self)

    class _Loader(Reader, Scanner, Parser, Composer, _Constructor, _Resolver):  # type: ignore[no-redef]
        def __init__(self, stream: str) -> None:
            Reader.__init__(self, stream)
            Scanner.__init__(self)
            Parser.__init__(self)
            Composer.__init__(self)
            _Constructor.__init__(self)
            _Resolver.__init__(self)


def check_depth(text: str) -> None:
    """Refuse nesting deeper than :data:`MAX_DEPTH` from the parser's events (made without
    recursion), before anything recurses on it or libyaml's scanner slows down with it."""
    events = Events(text)
    depth = 0
    try:
        while (event := events.get_event()) is not None:
            if isinstance(event, yaml.SequenceStartEvent | yaml.MappingStartEvent):
                depth += 1
                if depth > MAX_DEPTH:
                    raise yaml.YAMLError(f"nested deeper than {MAX_DEPTH} levels at line "
                                         f"{event.start_mark.line + 1}")  # fmt: skip
            elif isinstance(event, yaml.SequenceEndEvent | yaml.MappingEndEvent):
                depth -= 1
            elif isinstance(event, yaml.StreamEndEvent):
                break
    finally:
        events.dispose()


def load(text: str) -> Any:
    """The one YAML document in ``text`` as JSON values; raises :class:`yaml.YAMLError`."""
    check_depth(text)
    loader = _Loader(text)
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()


def message(e: yaml.YAMLError) -> str:
    where = getattr(e, "problem_mark", None)
    at = f" at line {where.line + 1} column {where.column + 1}" if where else ""
    return f"not valid YAML{at}: {getattr(e, 'problem', None) or e}"


def answer(text: str) -> tuple[dict[str, Any], bool]:
    """The answer to one document, and whether this process can go on decoding (not after
    it ran out of memory)."""
    try:
        return {"doc": load(text)}, True
    except yaml.YAMLError as e:
        return {"error": message(e)}, True
    except RecursionError:
        return {"error": "nested too deeply (arrays or objects inside each other)"}, True
    except MemoryError:
        return {"error": "the document takes too much memory to decode"}, False


def serve(inp: Any, out: Any) -> None:
    """Answer framed documents from ``inp`` on ``out`` until ``inp`` ends (the API closed it
    or stopped) or a document used up the memory."""
    head = struct.Struct(">Q")
    while len(raw := inp.read(head.size)) == head.size:
        (size,) = head.unpack(raw)
        text = inp.read(size).decode("utf-8")
        doc, more = answer(text)
        del text
        data = json.dumps(doc).encode("utf-8")
        del doc
        out.write(head.pack(len(data)) + data)
        out.flush()
        if not more:
            return


def main() -> None:
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY, MEMORY))
    os.nice(10)  # the API process answers first
    if "--serve" in sys.argv[1:]:
        serve(sys.stdin.buffer, sys.stdout.buffer)
        return
    doc, _ = answer(sys.stdin.buffer.read().decode("utf-8"))
    sys.stdout.write(json.dumps(doc))


if __name__ == "__main__":
    main()
