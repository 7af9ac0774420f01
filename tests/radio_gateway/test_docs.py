"""docs/radio.md stays true: its example configuration loads, its numbers hold."""

from __future__ import annotations

import re
from pathlib import Path

import msgspec

from radio_gateway.core.auth import AUTH_OVERHEAD_BYTES
from radio_gateway.core.frame import RECORD_HEADER_BYTES, frame_overhead
from radio_gateway.core.slots import TdmConfig, physical_limit
from radio_gateway.runtime.gateway import GatewayConfig
from tests.conftest import REPO

from .helpers import TIMING

DOC = (REPO / "docs" / "radio.md").read_text()


def test_the_example_configuration_loads(tmp_path: Path) -> None:
    block = re.search(r"```toml\n(.*?)```", DOC, re.S)
    assert block is not None
    cfg = msgspec.convert(msgspec.toml.decode(block.group(1).encode()), GatewayConfig)
    assert cfg.node_id == 7 and cfg.zenoh.connect == ("tcp/127.0.0.1:7447",)
    assert cfg.node_config().timing.rf_bps == 115_200
    assert cfg.radio.registers()["MY"] == 0xFFFF  # run_gateway puts the node id there


def test_the_numbers_in_the_doc() -> None:
    assert frame_overhead(14, 40 + RECORD_HEADER_BYTES) == 62
    assert AUTH_OVERHEAD_BYTES == 8
    for guard_ms, nodes in ((2, 16), (5, 13), (10, 9)):
        assert physical_limit(TIMING, TdmConfig(guard_s=guard_ms / 1000)) == nodes
        assert f"| {guard_ms} ms | 62 bytes | {nodes} " in DOC
