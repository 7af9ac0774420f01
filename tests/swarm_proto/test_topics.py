"""The key layout and the topic registry."""

from __future__ import annotations

import pytest
from hypothesis import given

from swarm_proto import MESSAGE_TYPES, Command, CommandKind, Vote, VoteScore
from swarm_proto.testing import messages
from swarm_proto.topics import ALIVE, COMMAND, STATUS, TOPICS, VOTE, key_of, match, topic_of
from tests.conftest import REPO


def test_every_message_type_has_exactly_one_topic() -> None:
    carried = [t.msg_type for t in TOPICS if t.msg_type is not None]
    assert len(carried) == len(set(carried))
    assert set(MESSAGE_TYPES) <= set(carried)


def test_keys() -> None:
    assert STATUS.key("lab", vehicle_id=7) == "bandada/lab/vehicle/7/status"
    assert STATUS.wildcard("lab") == "bandada/lab/vehicle/*/status"
    assert ALIVE.key("default", node_id=3) == "bandada/default/alive/3"
    cmd = Command(issuer_id=900, seq=4, kind=CommandKind.RTL)
    assert key_of("default", cmd) == "bandada/default/cmd/900"
    vote = Vote(mission_id=12, voter_id=5, scores=(VoteScore(5, 0.5),))
    assert key_of("s1", vote) == "bandada/s1/vote/12/5"
    assert VOTE.parse("s1", "bandada/s1/vote/12/5") == {"mission_id": "12", "voter_id": "5"}
    assert COMMAND.parse("s1", "bandada/s2/cmd/1") is None


@given(msg=messages())
def test_key_of_a_message_matches_its_topic(msg: object) -> None:
    key = key_of("field", msg)  # type: ignore[arg-type]
    found = match("field", key)
    assert found is not None and found[0] is topic_of(msg)  # type: ignore[arg-type]


@pytest.mark.parametrize("bad", ["", "a/b", "a*", "x" * 33, "sp ace"])
def test_swarm_names_are_checked(bad: str) -> None:
    with pytest.raises(ValueError, match="swarm name"):
        STATUS.key(bad, vehicle_id=1)


def test_keyspace_doc_is_generated_from_the_registry() -> None:
    from swarm_proto.keyspace_doc import render

    doc = (REPO / "docs" / "keyspace.md").read_text()
    assert doc == render(), "docs/keyspace.md is stale: run `make docs`"
