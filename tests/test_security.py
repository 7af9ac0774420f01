"""Mutual TLS and access control from `swarm-node certs make`, on 127.0.0.1: the router
admits only certificates of the swarm's CA; only the ground station's certificate may
publish commands and missions; a vehicle's certificate publishes only under its own id.
(tests/test_netns.py does the same across namespaces with the real processes.)"""

from __future__ import annotations

import json
import queue
import stat
import time
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest
import zenoh

from swarm_node.certs import acl_config, make_swarm_certs, parse_ids
from swarm_proto.session import ZenohSettings, open_session
from tests.conftest import free_tcp_port

pytestmark = pytest.mark.network


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("certs")
    make_swarm_certs(out, "default", [1, 2], [900], ["127.0.0.1"])
    return out


def _client(certs: Path, name: str, endpoint: str) -> zenoh.Session:
    return open_session(
        ZenohSettings(connect=(endpoint,), config_file=str(certs / f"{name}.json5"))
    )


@pytest.fixture
def router(certs: Path) -> Iterator[tuple[zenoh.Session, str]]:
    endpoint = f"tls/127.0.0.1:{free_tcp_port()}"
    session = open_session(
        ZenohSettings(mode="router", listen=(endpoint,), config_file=str(certs / "router.json5"))
    )
    yield session, endpoint
    session.close()


def test_certs_files_keys_private_and_configs_load(certs: Path) -> None:
    for name in ("ca", "router", "vehicle-1", "vehicle-2", "gcs-900"):
        assert (certs / f"{name}.pem").read_text().startswith("-----BEGIN CERTIFICATE-----")
        assert stat.S_IMODE((certs / f"{name}.key").stat().st_mode) == 0o600
    conf = zenoh.Config.from_file(str(certs / "router.json5"))
    assert json.loads(conf.get_json("access_control/default_permission")) == "deny"
    assert json.loads(conf.get_json("transport/link/tls/enable_mtls")) is True
    conf = zenoh.Config.from_file(str(certs / "vehicle-1.json5"))
    assert json.loads(conf.get_json("mode")) == "client"
    assert json.loads(conf.get_json("connect/endpoints")) == ["tls/127.0.0.1:7447"]


def test_certs_refuse_to_overwrite_a_ca_and_bad_ids(tmp_path: Path, certs: Path) -> None:
    with pytest.raises(ValueError, match="exists"):
        make_swarm_certs(certs, "default", [1], [900], ["127.0.0.1"])
    with pytest.raises(ValueError, match="share an id"):
        make_swarm_certs(tmp_path / "x", "default", [1], [1], ["127.0.0.1"])
    with pytest.raises(ValueError, match="router"):
        make_swarm_certs(tmp_path / "y", "default", [1], [900], [])
    assert parse_ids("1,2,5-7") == [1, 2, 5, 6, 7]


def test_acl_rules_per_vehicle() -> None:
    acl = acl_config("alpha", [3], [900])
    rules = {r["id"]: r for r in acl["rules"]}
    assert "bandada/alpha/vehicle/3/**" in rules["put-vehicle-3"]["key_exprs"]
    assert not any("cmd" in k for k in rules["put-vehicle-3"]["key_exprs"])
    assert "bandada/alpha/cmd/900" in rules["put-gcs-900"]["key_exprs"]
    assert {"id": "s-vehicle-3", "cert_common_names": ["vehicle-3"]} in acl["subjects"]


def _command(issuer: int) -> bytes:
    return f"command from {issuer}".encode()  # the router's ACL never looks inside


def test_only_the_ground_station_commands_and_vehicles_publish_as_themselves(
    certs: Path, router: tuple[zenoh.Session, str]
) -> None:
    _, endpoint = router
    v1 = _client(certs, "vehicle-1", endpoint)
    v2 = _client(certs, "vehicle-2", endpoint)
    gcs = _client(certs, "gcs-900", endpoint)
    got: queue.Queue[str] = queue.Queue()
    subs = [
        v1.declare_subscriber("bandada/default/cmd/*", lambda s: got.put(str(s.key_expr))),
        gcs.declare_subscriber("bandada/default/vehicle/*/ack", lambda s: got.put(str(s.key_expr))),
    ]
    try:
        ack = b"ack"
        deadline = time.monotonic() + 10
        while got.empty() and time.monotonic() < deadline:  # until the routes are up
            gcs.put("bandada/default/cmd/900", _command(900))
            time.sleep(0.2)
        assert got.get(timeout=1) == "bandada/default/cmd/900"
        v2.put("bandada/default/vehicle/2/ack", ack)  # its own id: delivered
        assert got.get(timeout=5) == "bandada/default/vehicle/2/ack"
        while not got.empty():
            got.get_nowait()
        # a vehicle's certificate: no command, as itself or as the ground station,
        # and no message under another vehicle's id
        v2.put("bandada/default/cmd/900", _command(900))
        v2.put("bandada/default/cmd/2", _command(2))
        v2.put("bandada/default/vehicle/1/ack", ack)
        v2.put("bandada/default/vehicle/2/ack", ack)  # a marker: this one passes
        assert got.get(timeout=5) == "bandada/default/vehicle/2/ack"
        time.sleep(0.5)
        assert got.empty()
    finally:
        for s in subs:
            s.undeclare()
        for session in (v1, v2, gcs):
            session.close()


def test_without_the_swarms_certificate_no_connection(
    tmp_path: Path, certs: Path, router: tuple[zenoh.Session, str]
) -> None:
    _, endpoint = router
    # TLS with the CA but no client certificate: the router refuses (mutual TLS)
    anon = json.loads(
        "\n".join(
            line
            for line in (certs / "gcs-900.json5").read_text().splitlines()
            if not line.startswith("//")
        )
    )
    tls = anon["transport"]["link"]["tls"]
    del tls["connect_certificate"], tls["connect_private_key"]
    (tmp_path / "anon.json5").write_text(json.dumps(anon))
    # another swarm's CA and certificates, including a "gcs-900"
    make_swarm_certs(tmp_path / "other", "default", [1], [900], ["127.0.0.1"])
    for config in (tmp_path / "anon.json5", tmp_path / "other" / "gcs-900.json5"):
        settings = ZenohSettings(connect=(endpoint,), config_file=str(config))
        with pytest.raises(zenoh.ZError):
            open_session(settings).close()
    # plain TCP to the TLS port: no session either
    plain = msgspec.structs.replace(
        ZenohSettings(mode="client"), connect=(endpoint.replace("tls/", "tcp/"),)
    )
    with pytest.raises(zenoh.ZError):
        open_session(plain).close()
