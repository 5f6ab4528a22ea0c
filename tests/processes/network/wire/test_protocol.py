"""The protocol document: its generated tables equal what the code says, so it cannot drift."""
from pathlib import Path

import pytest

from engine.play import rules
from processes.network import wire
from processes.network.wire import protocol

ROOT = Path(__file__).resolve().parents[4]
DOC = ROOT / "docs" / "protocol.md"


def test_the_documents_generated_tables_match_the_code():
    text = DOC.read_text()
    assert protocol.rewrite(text) == text, "docs/protocol.md is stale: run `make protocol`"


@pytest.mark.parametrize("kind", list(wire.Kind))
def test_each_docstring_layout_spells_the_dtypes_types(kind):
    spec = wire.SPECS[kind]
    rows = [row for row in protocol.docstring_rows(spec.__doc__) if row[2] != "header"]
    assert [(name, kind_) for _, _, name, kind_, _ in rows] == [
        (name, protocol.type_name(spec.dtype.fields[name][0])) for name in spec.names]
    assert all(meaning for *_, meaning in rows)  # every field says what it means


def test_every_enum_on_the_wire_is_published_with_every_member_named():
    text = DOC.read_text()
    for name, (cls, _, values) in protocol.ENUMS.items():
        assert f"<!-- protocol:enum_{name}:begin" in text
        block = protocol.blocks()[f"enum_{name}"]
        for member in cls:
            value = int(member.value) if values is None else values[member]
            label = member.name.lower() if isinstance(member.value, int) else member.value
            assert f"| {value} | `{label}` |" in block
            assert protocol.member_comments(cls)[member.name], f"{cls.__name__}.{member.name} has no comment"
    assert len(protocol.blocks()["enum_event_reason"].splitlines()) == 4 + len(rules.REASONS)


def test_rewrite_refuses_a_document_without_a_block():
    with pytest.raises(ValueError):
        protocol.rewrite("no blocks here")
