"""docs/database.md stays true: its table reference is generated from the metadata, and
the key selector layout it documents is the one the queryable serves."""

from __future__ import annotations

from swarm_node.database.queryable import RESOURCES
from swarm_node.database.tables import render_markdown
from swarm_proto.topics import DATABASE
from tests.conftest import REPO

DOC = REPO / "docs" / "database.md"


def test_the_table_reference_is_current() -> None:
    assert render_markdown() in DOC.read_text(), (
        "docs/database.md is stale: paste the output of `python -m swarm_node.database`"
    )


def test_the_documented_resources_are_served() -> None:
    text = DOC.read_text()
    for resource in ("profile", "profiles", "export", "table/<group>/<table>"):
        assert f"`db/<node_id>/{resource}" in text
    assert {"", "profile", "profiles", "export"} <= set(RESOURCES)
    assert "docs/database.md" in DATABASE.doc
