"""The wire's layouts: golden bytes, packed little-endian records sized and documented as their
docstrings say (processes.network.wire.messages)."""
import re

import pytest

from processes.network import wire
from processes.network.wire import Kind, Slot, encode
from tests.helpers.golden import GOLDEN, GOLDEN_FIELDS

EXPECTED_SIZES = {Kind.HELLO: 74, Kind.WELCOME: 166, Kind.REJECT: 89, Kind.INPUT: 130, Kind.SNAPSHOT: 338,
                  Kind.EVENT: 40, Kind.HEARTBEAT: 32, Kind.GOODBYE: 25, Kind.NET: 3891, Kind.SCENE_REQUEST: 32,
                  Kind.SCENE_PART: 4036}


# --- layouts -----------------------------------------------------------------------------------------------
def test_fourteen_golden_messages_cover_every_type():
    assert len(GOLDEN) == 14
    assert {kind for kind, _ in GOLDEN_FIELDS.values()} == set(Kind)


@pytest.mark.parametrize("kind", list(Kind))
def test_layout_is_packed_little_endian_and_sized_as_documented(kind):
    dtype = wire.SPECS[kind].dtype
    assert dtype.itemsize == EXPECTED_SIZES[kind] == wire.SIZES[kind]
    assert dtype.itemsize == sum(dtype.fields[name][0].itemsize for name in dtype.names)  # no padding
    for name in dtype.names:
        assert dtype.fields[name][0].base.str[0] in "<|", name  # explicit little-endian or single byte
    assert dtype.names[:6] == wire.HEADER_DTYPE.names and wire.HEADER_SIZE == 24


@pytest.mark.parametrize("kind", list(Kind))
def test_docstring_layout_lists_every_field_at_its_offset(kind):
    spec = wire.SPECS[kind]
    doc = spec.__doc__
    assert f"Layout, {spec.dtype.itemsize} bytes:" in doc
    rows = re.findall(r"^\s+(\d+)\s+(\d+)\s+(\w+)\s", doc.split("Layout")[1], re.MULTILINE)
    listed = {name: (int(offset), int(size)) for offset, size, name in rows}
    assert listed.pop("header") == (0, wire.HEADER_SIZE)
    actual = {name: (spec.dtype.fields[name][1], spec.dtype.fields[name][0].itemsize) for name in spec.names}
    assert listed == actual


def test_module_docstring_header_table_matches_the_header_dtype():
    rows = re.findall(r"^\s+(\d+)\s+(\d+)\s+(\w+)\s", wire.__doc__.split("Text fields")[0], re.MULTILINE)
    listed = {name: (int(offset), int(size)) for offset, size, name in rows}
    dtype = wire.HEADER_DTYPE
    assert listed == {name: (dtype.fields[name][1], dtype.fields[name][0].itemsize) for name in dtype.names}


def test_magic_and_version_are_the_first_six_bytes():
    for data in GOLDEN.values():
        assert data[:4] == b"PPNG" and data[4:6] == wire.PROTOCOL_VERSION.to_bytes(2, "little")


# --- golden messages ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(GOLDEN_FIELDS))
def test_golden_message_bytes(name):
    kind, fields = GOLDEN_FIELDS[name]
    assert encode(kind, **fields) == GOLDEN[name]
    assert encode(kind.name.lower(), **fields) == GOLDEN[name]  # by name too


def test_a_seat_names_its_bat_and_a_spectator_has_none():
    assert (Slot.A.bat, Slot.B.bat) == (0, 1)  # the engine's player 0 plays at x < 0 (wire.Slot)
    assert [Slot.of_bat(bat) for bat in (0, 1)] == [Slot.A, Slot.B]
    with pytest.raises(ValueError, match="has no bat"):
        Slot.NONE.bat
