#!/usr/bin/env python3
"""Generate the protocol code from protocol/messages.yaml (the single source of truth).

Usage:
    python scripts/gen_protocol.py           # (re)write the generated files
    python scripts/gen_protocol.py --check   # exit 1 if any generated file is stale

Generated targets:
    host/tsa_bench/protocol/catalogue.py   typed message classes, enums, specs, hash
    protocol/messages.md                   the message table for humans
    firmware/core/protocol_catalogue.h     C++ ids, enums, message structs, pack/unpack
    firmware/tests/golden_vectors.inc      protocol/vectors.json as C++ data for native tests

The catalogue hash is CRC-32 of the catalogue's canonical JSON (sorted keys, no
whitespace, comments and `doc` strings dropped), so editing documentation does not
change it but editing any id, name, field, type, unit or enum value does.
"""

from __future__ import annotations

import argparse
import json
import re
import struct
import sys
import zlib
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
CATALOGUE = ROOT / "protocol" / "messages.yaml"
PY_OUT = ROOT / "host" / "tsa_bench" / "protocol" / "catalogue.py"
MD_OUT = ROOT / "protocol" / "messages.md"
C_OUT = ROOT / "firmware" / "core" / "protocol_catalogue.h"
VECTORS_IN = ROOT / "protocol" / "vectors.json"
VECTORS_OUT = ROOT / "firmware" / "tests" / "golden_vectors.inc"

TYPES = {"u8": "B", "u16": "H", "u32": "I", "u64": "Q", "i8": "b", "i16": "h", "i32": "i", "i64": "q", "f32": "f"}
PY_TYPES = {t: ("float" if t == "f32" else "int") for t in TYPES}
IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
ENUM_CLASS = {
    "status": ("Status", "IntEnum"),
    "event_kind": ("EventKind", "IntEnum"),
    "fault": ("Fault", "IntEnum"),
    "boot_reason": ("BootReason", "IntEnum"),
    "adc_flags": ("AdcFlags", "IntFlag"),
    "sample_flags": ("SampleFlags", "IntFlag"),
    "device_flags": ("DeviceFlags", "IntFlag"),
    "device_state": ("DeviceState", "IntFlag"),
}


class CatalogueError(Exception):
    pass


def load_catalogue(path: Path = CATALOGUE) -> dict:
    """Read and check the catalogue; raise CatalogueError naming the message and field."""
    cat = yaml.safe_load(path.read_text())
    ids: set[int] = set()
    names: set[str] = set()
    for msg in cat["messages"]:
        where = f"{path.name}: message {msg.get('name', '?')}"
        if not IDENT.match(msg["name"]) or msg["name"] in names:
            raise CatalogueError(f"{where}: bad or duplicate name")
        if not 0 < msg["id"] < 256 or msg["id"] in ids:
            raise CatalogueError(f"{where}: id {msg['id']} outside 1..255 or duplicate")
        if msg["dir"] not in ("host", "device"):
            raise CatalogueError(f"{where}: dir must be host or device")
        ids.add(msg["id"])
        names.add(msg["name"])
        seen: set[str] = set()
        for f in msg["fields"]:
            if f["type"] not in TYPES:
                raise CatalogueError(f"{where}: field {f['name']}: unknown type {f['type']}")
            if not IDENT.match(f["name"]) or f["name"] in seen:
                raise CatalogueError(f"{where}: field {f['name']}: bad or duplicate name")
            seen.add(f["name"])
        size = struct.calcsize("<" + "".join(TYPES[f["type"]] for f in msg["fields"]))
        entries = msg.get("entries")
        if entries is not None:
            counts = [f for f in msg["fields"] if f["name"] == entries["count_field"]]
            if not counts or counts[0]["type"] != "u8":
                raise CatalogueError(f"{where}: entries: count_field {entries['count_field']} is not a u8 field")
            if msg["dir"] != "device":
                raise CatalogueError(f"{where}: entries: only device messages may have a variable length")
            for f in entries["fields"]:
                if f["type"] not in TYPES or not IDENT.match(f["name"]):
                    raise CatalogueError(f"{where}: entry field {f['name']}: bad name or type")
            size += entries["max"] * struct.calcsize("<" + "".join(TYPES[f["type"]] for f in entries["fields"]))
        if size > cat["max_payload"]:
            raise CatalogueError(f"{where}: payload {size} B exceeds max_payload {cat['max_payload']}")
    for enum in cat["enums"]:
        if enum not in ENUM_CLASS:
            raise CatalogueError(f"{path.name}: enum {enum} has no class name in gen_protocol.py")
    return cat


def _wire_only(node):
    """The catalogue without its documentation: what actually shapes the bytes."""
    if isinstance(node, dict):
        return {k: _wire_only(v) for k, v in node.items() if k != "doc"}
    if isinstance(node, list):
        return [_wire_only(v) for v in node]
    return node


def catalogue_hash(cat: dict) -> int:
    canonical = json.dumps(_wire_only(cat), sort_keys=True, separators=(",", ":"))
    return zlib.crc32(canonical.encode()) & 0xFFFFFFFF


def camel(name: str) -> str:
    return "".join(p.capitalize() for p in name.lower().split("_"))


def render_python(cat: dict) -> str:
    h = catalogue_hash(cat)
    out = [
        '"""Protocol catalogue: GENERATED by scripts/gen_protocol.py from protocol/messages.yaml.',
        "",
        "Do not edit by hand; edit the catalogue and run the generator. CI fails when stale.",
        '"""',
        "",
        "from __future__ import annotations",
        "",
        "import struct",
        "from dataclasses import dataclass",
        "from enum import IntEnum, IntFlag",
        "from typing import NamedTuple",
        "",
        f"PROTOCOL_VERSION = {cat['protocol_version']}",
        f"CATALOGUE_HASH = 0x{h:08X}",
        f"MAX_PAYLOAD = {cat['max_payload']}",
        "",
    ]
    for enum, values in cat["enums"].items():
        cls, base = ENUM_CLASS[enum]
        out += ["", f"class {cls}({base}):", f'    """Catalogue enum `{enum}`."""', ""]
        out += [f"    {k.upper()} = {v}" for k, v in values.items()]
        out.append("")
    for msg in cat["messages"]:
        cls = camel(msg["name"])
        entries = msg.get("entries")
        if entries:
            out += ["", f"class {cls}Entry(NamedTuple):",
                    f'    """One entry of {msg["name"]} (up to {entries["max"]}, `{entries["count_field"]}` of them).', ""]
            for f in entries["fields"]:
                unit = f" [{f['units']}]" if "units" in f else ""
                out.append(f"    {f['name']} ({f['type']}{unit}): {f['doc']}")
            out += ['    """', ""] + [f"    {f['name']}: {PY_TYPES[f['type']]}" for f in entries["fields"]] + [""]
        out += ["", f"class {cls}(NamedTuple):"]
        doc = [f'    """{msg["name"]} (0x{msg["id"]:02X}, {msg["dir"]} -> '
               f'{"device" if msg["dir"] == "host" else "host"}): {msg["doc"]}']
        if msg["fields"]:
            doc.append("")
            for f in msg["fields"]:
                unit = f" [{f['units']}]" if "units" in f else ""
                doc.append(f"    {f['name']} ({f['type']}{unit}): {f['doc']}")
        doc.append('    """')
        out += doc
        if msg["fields"]:
            out += [""] + [f"    {f['name']}: {PY_TYPES[f['type']]}" for f in msg["fields"]]
        if entries:
            out.append(f"    entries: tuple[{cls}Entry, ...] = ()")
        out.append("")
    out += [
        "",
        "@dataclass(frozen=True)",
        "class MessageSpec:",
        '    """How one message is laid out on the wire."""',
        "",
        "    name: str",
        "    id: int",
        "    direction: str",
        "    queued: bool",
        "    cls: type",
        "    struct: struct.Struct",
        "    units: dict[str, str]",
        "    #: variable-length messages: the struct of one entry, its class, the most entries and",
        "    #: the index of the field that counts them (the message's last field, `entries`, holds them)",
        "    entry_struct: struct.Struct | None = None",
        "    entry_cls: type | None = None",
        "    max_entries: int = 0",
        "    count_index: int = -1",
        "",
        "",
        "MESSAGES: dict[int, MessageSpec] = {",
    ]
    for msg in cat["messages"]:
        fmt = "<" + "".join(TYPES[f["type"]] for f in msg["fields"])
        units = {f["name"]: f["units"] for f in msg["fields"] if "units" in f}
        extra = ""
        entries = msg.get("entries")
        if entries:
            efmt = "<" + "".join(TYPES[f["type"]] for f in entries["fields"])
            index = [f["name"] for f in msg["fields"]].index(entries["count_field"])
            extra = (f", struct.Struct({efmt!r}), {camel(msg['name'])}Entry, {entries['max']}, {index}")
        out.append(
            f"    0x{msg['id']:02X}: MessageSpec({msg['name']!r}, 0x{msg['id']:02X}, {msg['dir']!r}, "
            f"{bool(msg.get('queued', False))}, {camel(msg['name'])}, struct.Struct({fmt!r}), {units!r}{extra}),"
        )
    out += [
        "}",
        "",
        "SPEC_BY_CLASS: dict[type, MessageSpec] = {spec.cls: spec for spec in MESSAGES.values()}",
        "",
    ]
    return "\n".join(out)


C_TYPES = {"u8": "uint8_t", "u16": "uint16_t", "u32": "uint32_t", "u64": "uint64_t", "i8": "int8_t",
           "i16": "int16_t", "i32": "int32_t", "i64": "int64_t", "f32": "uint32_t"}
C_SIZES = {t: struct.calcsize("<" + c) for t, c in TYPES.items()}


def _c_field_io(fields: list[dict]) -> tuple[list[str], list[str]]:
    """Statements that load fields from ``p`` and store them to ``p`` (little-endian)."""
    loads, stores, off = [], [], 0
    for f in fields:
        n, ctype, size = f["name"], C_TYPES[f["type"]], C_SIZES[f["type"]]
        utype = f"uint{size * 8}_t"
        loads.append(f"    m.{n} = static_cast<{ctype}>(get_le<{utype}>(p + {off}));")
        stores.append(f"    put_le<{utype}>(p + {off}, static_cast<{utype}>(m.{n}));")
        off += size
    return loads, stores


def _offset(fields: list[dict], name: str) -> int:
    """Byte offset of a field in a payload."""
    off = 0
    for f in fields:
        if f["name"] == name:
            return off
        off += C_SIZES[f["type"]]
    raise KeyError(name)


def _flat(values: list) -> list:
    """Field values with nested entries flattened, in wire order."""
    out: list = []
    for v in values:
        if isinstance(v, (list, tuple)):
            out += _flat(list(v))
        else:
            out.append(v)
    return out


def render_c_header(cat: dict) -> str:
    h = catalogue_hash(cat)
    out = [
        "// Protocol catalogue: GENERATED by scripts/gen_protocol.py from protocol/messages.yaml.",
        "// Do not edit by hand; edit the catalogue and run the generator. CI fails when stale.",
        "// Portable C++11 (no STL, no AVR headers): message ids, enums, payload structs and",
        "// explicit little-endian pack/unpack, so the layout never depends on the compiler.",
        "#pragma once",
        "#include <stdint.h>",
        "#include <string.h>",
        "",
        "namespace proto {",
        "",
        f"static const uint8_t PROTOCOL_VERSION = {cat['protocol_version']};",
        f"static const uint32_t CATALOGUE_HASH = 0x{h:08X}UL;",
        f"static const uint8_t MAX_PAYLOAD = {cat['max_payload']};",
        "",
        "// Little-endian fields. On little-endian targets (the AVR, x86) a fixed-size memcpy,",
        "// which compilers turn into plain loads and stores: the byte loop's variable shifts",
        "// are library loops on the AVR, and SAMPLEs are packed hundreds of times a second.",
        "#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__",
        "template <typename T> inline T get_le(const uint8_t* p) {",
        "    T v;",
        "    memcpy(&v, p, sizeof(T));",
        "    return v;",
        "}",
        "template <typename T> inline void put_le(uint8_t* p, T v) { memcpy(p, &v, sizeof(T)); }",
        "#else",
        "template <typename T> inline T get_le(const uint8_t* p) {",
        "    T v = 0;",
        "    for (uint8_t i = 0; i < sizeof(T); ++i) v |= static_cast<T>(static_cast<T>(p[i]) << (8 * i));",
        "    return v;",
        "}",
        "template <typename T> inline void put_le(uint8_t* p, T v) {",
        "    for (uint8_t i = 0; i < sizeof(T); ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));",
        "}",
        "#endif",
        "",
    ]
    for enum, values in cat["enums"].items():
        out.append(f"namespace {enum} {{")
        out += [f"static const uint8_t {k.upper()} = {v};" if v < 256 else
                f"static const uint16_t {k.upper()} = {v};" for k, v in values.items()]
        out += [f"}}  // namespace {enum}", ""]
    out.append("namespace id {")
    out += [f"static const uint8_t {m['name']} = 0x{m['id']:02X};" for m in cat["messages"]]
    out += ["}  // namespace id", ""]
    for m in cat["messages"]:
        cls = camel(m["name"])
        size = sum(C_SIZES[f["type"]] for f in m["fields"])
        entries = m.get("entries")
        if entries:
            esize = sum(C_SIZES[f["type"]] for f in entries["fields"])
            out.append(f"// One entry of {m['name']} (`{entries['count_field']}` of them follow the fixed fields).")
            out.append(f"struct {cls}Entry {{")
            for f in entries["fields"]:
                unit = f" [{f['units']}]" if "units" in f else ""
                out.append(f"    {C_TYPES[f['type']]} {f['name']};  // {f['doc']}{unit}")
            out.append("};")
        arrow = "host -> device" if m["dir"] == "host" else "device -> host"
        out.append(f"// {m['name']} (0x{m['id']:02X}, {arrow}{', queued' if m.get('queued') else ''}): {m['doc']}")
        out.append(f"struct {cls} {{")
        out.append(f"    static const uint8_t ID = 0x{m['id']:02X};")
        out.append(f"    static const uint8_t SIZE = {size};")
        if entries:
            out.append(f"    static const uint8_t ENTRY_SIZE = {esize};")
            out.append(f"    static const uint8_t MAX_ENTRIES = {entries['max']};")
        for f in m["fields"]:
            unit = f" [{f['units']}]" if "units" in f else ""
            out.append(f"    {C_TYPES[f['type']]} {f['name']};  // {f['doc']}{unit}")
        if entries:
            out.append(f"    {cls}Entry entries[{entries['max']}];  // the first `{entries['count_field']}` are sent")
        out.append("};")
        loads, stores = _c_field_io(m["fields"])
        unused = "" if m["fields"] else "(void)p; (void)m; "
        out.append(f"inline void unpack(const uint8_t* p, {cls}& m) {{ {unused}")
        out += loads
        if entries:
            eloads, _ = _c_field_io(entries["fields"])
            n = entries["count_field"]
            out.append(f"    if (m.{n} > {entries['max']}) m.{n} = {entries['max']};")
            out.append(f"    for (uint8_t i = 0; i < m.{n}; ++i) {{")
            out.append(f"        const uint8_t* q = p + {size} + i * {esize};")
            out.append(f"        {cls}Entry& e = m.entries[i];")
            out += ["    " + x.replace("m.", "e.").replace("(p + ", "(q + ") for x in eloads]
            out.append("    }")
        out.append("}")
        out.append(f"inline uint8_t pack(const {cls}& m, uint8_t* p) {{ {unused}")
        out += stores
        if entries:
            _, estores = _c_field_io(entries["fields"])
            n = entries["count_field"]
            out.append(f"    const uint8_t n = m.{n} > {entries['max']} ? {entries['max']} : m.{n};")
            out.append(f"    p[{_offset(m['fields'], n)}] = n;")
            out.append("    for (uint8_t i = 0; i < n; ++i) {")
            out.append(f"        uint8_t* q = p + {size} + i * {esize};")
            out.append(f"        const {cls}Entry& e = m.entries[i];")
            out += ["    " + x.replace("m.", "e.").replace("(p + ", "(q + ") for x in estores]
            out.append("    }")
            out.append(f"    return static_cast<uint8_t>({size} + n * {esize});")
        else:
            out.append(f"    return {size};")
        out.append("}")
        out.append("")
    out.append("// Payload size of a message id, or -1 when the id is not in the catalogue.")
    out.append("inline int16_t payload_size(uint8_t msg_id) {")
    out.append("    switch (msg_id) {")
    out += [f"    case 0x{m['id']:02X}: return {sum(C_SIZES[f['type']] for f in m['fields'])};"
            for m in cat["messages"]]
    out += ["    default: return -1;", "    }", "}", ""]
    out.append("// Length of a received payload as its own count field says (variable-length messages),")
    out.append("// else payload_size(msg_id). Needs the fixed fields present (payload_size bytes).")
    out.append("inline int16_t payload_length(uint8_t msg_id, const uint8_t* p) {")
    out.append("    switch (msg_id) {")
    for m in cat["messages"]:
        if m.get("entries"):
            e = m["entries"]
            esize = sum(C_SIZES[f["type"]] for f in e["fields"])
            base = sum(C_SIZES[f["type"]] for f in m["fields"])
            out.append(f"    case 0x{m['id']:02X}: return static_cast<int16_t>({base} + "
                       f"p[{_offset(m['fields'], e['count_field'])}] * {esize});")
    out += ["    default: (void)p; return payload_size(msg_id);", "    }", "}", ""]
    out.append("// Whether a host message goes into the device's command queue.")
    out.append("inline bool is_queued(uint8_t msg_id) {")
    queued = [m for m in cat["messages"] if m.get("queued")]
    out.append("    return " + " || ".join(f"msg_id == 0x{m['id']:02X}" for m in queued) + ";")
    out += ["}", ""]
    most = max(len(m["fields"]) + (m["entries"]["max"] * len(m["entries"]["fields"]) if m.get("entries") else 0)
               for m in cat["messages"])
    out.append("// Most values decode_fields() writes (a variable-length message's entries flattened).")
    out.append(f"static const uint8_t MAX_DECODED_FIELDS = {most};")
    out.append("")
    out.append("// Every field of a payload, in catalogue order (then each entry's), widened to int64 (for tests and tools).")
    out.append("inline uint8_t decode_fields(uint8_t msg_id, const uint8_t* p, int64_t* out) {")
    out.append("    switch (msg_id) {")
    for m in cat["messages"]:
        out.append(f"    case 0x{m['id']:02X}: {{")
        off = 0
        for i, f in enumerate(m["fields"]):
            size = C_SIZES[f["type"]]
            out.append(f"        out[{i}] = static_cast<{C_TYPES[f['type']]}>(get_le<uint{size * 8}_t>(p + {off}));")
            off += size
        if not m["fields"]:
            out.append("        (void)p; (void)out;")
        e = m.get("entries")
        if e:
            esize = sum(C_SIZES[f["type"]] for f in e["fields"])
            nf = len(m["fields"])
            out.append(f"        const uint8_t n = p[{_offset(m['fields'], e['count_field'])}] > {e['max']} ? "
                       f"{e['max']} : p[{_offset(m['fields'], e['count_field'])}];")
            out.append("        for (uint8_t i = 0; i < n; ++i) {")
            out.append(f"            const uint8_t* q = p + {off} + i * {esize};")
            eoff = 0
            for j, f in enumerate(e["fields"]):
                size = C_SIZES[f["type"]]
                out.append(f"            out[{nf} + i * {len(e['fields'])} + {j}] = "
                           f"static_cast<{C_TYPES[f['type']]}>(get_le<uint{size * 8}_t>(q + {eoff}));")
                eoff += size
            out.append("        }")
            out.append(f"        return static_cast<uint8_t>({nf} + n * {len(e['fields'])});")
        else:
            out.append(f"        return {len(m['fields'])};")
        out.append("    }")
    out += ["    default: return 0;", "    }", "}", "", "}  // namespace proto", ""]
    return "\n".join(out)


def render_c_vectors(vectors: dict) -> str:
    def arr(hexstr: str) -> str:
        b = bytes.fromhex(hexstr)
        return "{" + ", ".join(f"0x{x:02X}" for x in b) + "}" if b else "{0}"

    out = [
        "// Golden vectors: GENERATED by scripts/gen_protocol.py from protocol/vectors.json.",
        "// The same frames the Python suite checks; included by the native framing tests.",
        "// Message vectors: name, seq, msg id, fields (catalogue order), frame incl. delimiter.",
        "",
    ]
    ids = {}
    for i, v in enumerate(vectors["messages"]):
        frame = bytes.fromhex(v["frame"])
        fields = _flat(list(v["fields"].values()))
        out.append(f"static const uint8_t gv_msg_frame_{i}[] = {arr(v['frame'])};")
        out.append(f"static const int64_t gv_msg_fields_{i}[] = {{{', '.join(str(x) + 'LL' for x in fields) or '0'}}};")
        ids[i] = (v, len(frame), len(fields))
    out.append("static const GoldenMessage GOLDEN_MESSAGES[] = {")
    for i, (v, n, nf) in ids.items():
        out.append(f'    {{"{v["name"]}", {v["seq"]}, gv_msg_frame_{i}, {n}, gv_msg_fields_{i}, {nf}}},')
    out += ["};", ""]
    for i, v in enumerate(vectors["frames"]):
        out.append(f"static const uint8_t gv_frame_{i}[] = {arr(v['frame'])};")
        out.append(f"static const uint8_t gv_frame_payload_{i}[] = {arr(v['payload'])};")
    out.append("static const GoldenFrame GOLDEN_FRAMES[] = {")
    for i, v in enumerate(vectors["frames"]):
        n = len(bytes.fromhex(v["frame"]))
        out.append(f'    {{"{v["case"]}", 0x{v["msg_id"]:02X}, {v["seq"]}, gv_frame_payload_{i}, '
                   f'{len(bytes.fromhex(v["payload"]))}, gv_frame_{i}, {n}}},')
    out += ["};", ""]
    for i, v in enumerate(vectors["invalid"]):
        out.append(f"static const uint8_t gv_invalid_{i}[] = {arr(v['stuffed'])};")
    out.append("static const GoldenInvalid GOLDEN_INVALID[] = {")
    for i, v in enumerate(vectors["invalid"]):
        out.append(f'    {{"{v["case"]}", "{v["reason"]}", gv_invalid_{i}, {len(bytes.fromhex(v["stuffed"]))}}},')
    out += ["};", ""]
    return "\n".join(out)


def render_markdown(cat: dict) -> str:
    out = [
        "# Message catalogue",
        "",
        "GENERATED by `scripts/gen_protocol.py` from `messages.yaml`; do not edit.",
        "",
        f"Protocol version {cat['protocol_version']}, catalogue hash `0x{catalogue_hash(cat):08X}`, "
        f"maximum payload {cat['max_payload']} bytes. All fields little-endian.",
        "",
    ]
    for msg in cat["messages"]:
        fmt = "<" + "".join(TYPES[f["type"]] for f in msg["fields"])
        arrow = "host → device" if msg["dir"] == "host" else "device → host"
        queued = ", queued" if msg.get("queued") else ""
        out += [f"## `0x{msg['id']:02X}` {msg['name']} ({arrow}{queued}, {struct.calcsize(fmt)} B)", "",
                msg["doc"], ""]
        if msg["fields"]:
            out += ["| offset | field | type | units | meaning |", "|---|---|---|---|---|"]
            off = 0
            for f in msg["fields"]:
                out.append(f"| {off} | `{f['name']}` | {f['type']} | {f.get('units', '')} | {f['doc']} |")
                off += struct.calcsize("<" + TYPES[f["type"]])
            out.append("")
        e = msg.get("entries")
        if e:
            efmt = "<" + "".join(TYPES[f["type"]] for f in e["fields"])
            out += [f"Then `{e['count_field']}` entries (at most {e['max']}) of {struct.calcsize(efmt)} B each:", "",
                    "| offset in entry | field | type | units | meaning |", "|---|---|---|---|---|"]
            off = 0
            for f in e["fields"]:
                out.append(f"| {off} | `{f['name']}` | {f['type']} | {f.get('units', '')} | {f['doc']} |")
                off += struct.calcsize("<" + TYPES[f["type"]])
            out.append("")
    out += ["# Enumerations", ""]
    for enum, values in cat["enums"].items():
        out += [f"## {enum}", "", "| name | value |", "|---|---|"]
        out += [f"| `{k}` | {v} |" for k, v in values.items()]
        out.append("")
    return "\n".join(out)


def _rel(path: Path) -> str:
    try:
        return str(path.relative_to(ROOT))
    except ValueError:
        return str(path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="fail if generated files are stale")
    args = ap.parse_args(argv)
    try:
        cat = load_catalogue()
    except CatalogueError as exc:
        print(f"protocol catalogue error: {exc}", file=sys.stderr)
        return 2
    targets = {PY_OUT: render_python(cat), MD_OUT: render_markdown(cat), C_OUT: render_c_header(cat),
               VECTORS_OUT: render_c_vectors(json.loads(VECTORS_IN.read_text()))}
    stale = []
    for path, text in targets.items():
        current = path.read_text() if path.exists() else None
        if current != text:
            if args.check:
                stale.append(path)
            else:
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text(text)
                print(f"wrote {_rel(path)}")
    if stale:
        for path in stale:
            print(f"stale generated file: {_rel(path)} "
                  "(run: python scripts/gen_protocol.py)", file=sys.stderr)
        return 1
    if args.check:
        print(f"generated protocol files are up to date (catalogue hash 0x{catalogue_hash(cat):08X})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
