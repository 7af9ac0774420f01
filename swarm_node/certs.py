"""A swarm's certificate authority, per-host certificates and the Zenoh configs that use
them: mutual TLS to the lab router, and the router's access control (docs/security.md).

`swarm-node certs make --out DIR --vehicles 1,2,3 --gcs 900 --router-host 10.77.0.1`
writes, for one swarm:

- `ca.pem` / `ca.key`: the swarm's CA (keep `ca.key` off the vehicles);
- `router.pem|key`, `vehicle-<id>.pem|key`, `gcs-<id>.pem|key`: one certificate per
  host, its common name the host's role and id (the ACL's subjects);
- `router.json5`: the router's Zenoh config: TLS listener with `enable_mtls`, and an
  `access_control` block, default deny, generated per vehicle;
- `vehicle-<id>.json5`, `gcs-<id>.json5`: each host's Zenoh config (client of the
  router over TLS), for `swarm-node run --zenoh-config` and `gcs --zenoh-config`.

Keys are EC P-256, written 0600. Paths inside the JSON5 files are those under
`--install-dir` (default: the output directory), where the files will live on the hosts.
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import json
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from swarm_proto.topics import check_swarm_name

ROUTER_PORT = 7447

# what every member of the swarm may do through the router (reads, queryables, replies)
_MEMBER_INGRESS = [
    "declare_subscriber",
    "declare_queryable",
    "query",
    "reply",
    "declare_liveliness_subscriber",
    "liveliness_query",
]
# what the router may pass on to a member
_MEMBER_EGRESS = [
    "put",
    "delete",
    "query",
    "reply",
    "declare_subscriber",
    "declare_queryable",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
]


def vehicle_cn(node_id: int) -> str:
    return f"vehicle-{node_id}"


def gcs_cn(node_id: int) -> str:
    return f"gcs-{node_id}"


def acl_config(swarm: str, vehicles: Iterable[int], gcs: Iterable[int]) -> dict[str, Any]:
    """The router's `access_control` block: default deny; members read everything of
    their swarm; only ground stations put commands, missions, zones and fleet
    assignments; each vehicle puts only under its own id (status, info, acks, alerts,
    votes, targets, liveliness). Zenoh ACL keys cannot refer to the subject, so the
    per-vehicle rules are generated, one rule and one subject per vehicle."""
    check_swarm_name(swarm)
    root = f"bandada/{swarm}"
    vehicles, gcs = sorted(set(vehicles)), sorted(set(gcs))
    members = [f"s-{vehicle_cn(v)}" for v in vehicles] + [f"s-{gcs_cn(g)}" for g in gcs]
    rules: list[dict[str, Any]] = [
        {
            "id": "member-read",
            "messages": _MEMBER_INGRESS,
            "flows": ["ingress"],
            "permission": "allow",
            "key_exprs": [f"{root}/**"],
        },
        {
            "id": "member-receive",
            "messages": _MEMBER_EGRESS,
            "flows": ["egress"],
            "permission": "allow",
            "key_exprs": [f"{root}/**"],
        },
    ]
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = [
        {"id": "members", "rules": ["member-read", "member-receive"], "subjects": members}
    ]
    for g in gcs:
        rules.append(
            {
                "id": f"put-{gcs_cn(g)}",
                "messages": ["put", "delete", "liveliness_token"],
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": [
                    f"{root}/cmd/{g}",
                    f"{root}/mission/*",
                    f"{root}/zone/*",
                    f"{root}/fleet/*",
                    f"{root}/target/{g}/*",
                    f"{root}/alive/{g}",
                ],
            }
        )
        subjects.append({"id": f"s-{gcs_cn(g)}", "cert_common_names": [gcs_cn(g)]})
        policies.append(
            {"id": f"p-{gcs_cn(g)}", "rules": [f"put-{gcs_cn(g)}"], "subjects": [f"s-{gcs_cn(g)}"]}
        )
    for v in vehicles:
        rules.append(
            {
                "id": f"put-{vehicle_cn(v)}",
                "messages": ["put", "delete", "liveliness_token"],
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": [
                    f"{root}/vehicle/{v}/**",
                    f"{root}/vote/*/{v}",
                    f"{root}/target/{v}/*",
                    f"{root}/alive/{v}",
                ],
            }
        )
        subjects.append({"id": f"s-{vehicle_cn(v)}", "cert_common_names": [vehicle_cn(v)]})
        policies.append(
            {
                "id": f"p-{vehicle_cn(v)}",
                "rules": [f"put-{vehicle_cn(v)}"],
                "subjects": [f"s-{vehicle_cn(v)}"],
            }
        )
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def _tls(dir_: Path, name: str, *, listen: bool, connect: bool) -> dict[str, Any]:
    tls: dict[str, Any] = {"root_ca_certificate": str(dir_ / "ca.pem"), "enable_mtls": True}
    if listen:
        tls["listen_certificate"] = str(dir_ / f"{name}.pem")
        tls["listen_private_key"] = str(dir_ / f"{name}.key")
    if connect:
        tls["connect_certificate"] = str(dir_ / f"{name}.pem")
        tls["connect_private_key"] = str(dir_ / f"{name}.key")
    return tls


def _lease() -> dict[str, Any]:
    return {"lease": 2000, "keep_alive": 4}


def router_config(
    install_dir: Path,
    swarm: str,
    vehicles: Iterable[int],
    gcs: Iterable[int],
    listen: Sequence[str] = (f"tls/0.0.0.0:{ROUTER_PORT}",),
) -> dict[str, Any]:
    return {
        "mode": "router",
        "listen": {"endpoints": list(listen)},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": True}},
        "transport": {
            "link": {"tx": _lease(), "tls": _tls(install_dir, "router", listen=True, connect=True)}
        },
        "access_control": acl_config(swarm, vehicles, gcs),
    }


def client_config(install_dir: Path, name: str, connect: Sequence[str]) -> dict[str, Any]:
    return {
        "mode": "client",
        "connect": {"endpoints": list(connect)},
        "scouting": {"multicast": {"enabled": False}},
        "transport": {
            "link": {"tx": _lease(), "tls": _tls(install_dir, name, listen=False, connect=True)}
        },
    }


def _write_key(path: Path, key: Any) -> None:
    from cryptography.hazmat.primitives import serialization

    data = key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.chmod(path, 0o600)


def _write_cert(path: Path, cert: Any) -> None:
    from cryptography.hazmat.primitives import serialization

    path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))


def _san(hosts: Iterable[str]) -> list[Any]:
    from cryptography import x509

    names: list[Any] = []
    for h in hosts:
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(h)))
        except ValueError:
            names.append(x509.DNSName(h))
    return names


def make_swarm_certs(
    out: Path,
    swarm: str,
    vehicles: Sequence[int],
    gcs: Sequence[int],
    router_hosts: Sequence[str],
    *,
    install_dir: Path | None = None,
    days: int = 825,
) -> list[Path]:
    """Write the CA, the router's, every vehicle's and ground station's certificate and
    key, and the Zenoh configs; returns the files written. Refuses to overwrite a CA."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    check_swarm_name(swarm)
    if not router_hosts:
        raise ValueError("name the router's address or host name (--router-host)")
    for i in [*vehicles, *gcs]:
        if not 1 <= i <= 65534:
            raise ValueError(f"node ids are 1..65534, got {i}")
    if set(vehicles) & set(gcs):
        raise ValueError("a vehicle and a ground station share an id")
    out.mkdir(parents=True, exist_ok=True)
    if (out / "ca.key").exists():
        raise ValueError(f"{out / 'ca.key'} exists: use a new directory for a new swarm CA")
    install = install_dir or out.resolve()
    now = dt.datetime.now(dt.UTC) - dt.timedelta(minutes=5)
    until = now + dt.timedelta(days=days)
    written: list[Path] = []

    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name(
        [
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "bandada"),
            x509.NameAttribute(NameOID.COMMON_NAME, f"bandada swarm {swarm} CA"),
        ]
    )
    ca = (
        x509.CertificateBuilder()
        .subject_name(ca_name)
        .issuer_name(ca_name)
        .public_key(ca_key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now)
        .not_valid_after(until)
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(ca_key.public_key()), False)
        .sign(ca_key, hashes.SHA256())
    )
    _write_key(out / "ca.key", ca_key)
    _write_cert(out / "ca.pem", ca)
    written += [out / "ca.pem", out / "ca.key"]

    def leaf(name: str, hosts: Sequence[str]) -> None:
        key = ec.generate_private_key(ec.SECP256R1())
        subject = x509.Name(
            [
                x509.NameAttribute(NameOID.ORGANIZATION_NAME, "bandada"),
                x509.NameAttribute(NameOID.ORGANIZATIONAL_UNIT_NAME, swarm),
                x509.NameAttribute(NameOID.COMMON_NAME, name),
            ]
        )
        cert = (
            x509.CertificateBuilder()
            .subject_name(subject)
            .issuer_name(ca_name)
            .public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now)
            .not_valid_after(until)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(
                x509.KeyUsage(
                    digital_signature=True,
                    content_commitment=False,
                    key_encipherment=False,
                    data_encipherment=False,
                    key_agreement=False,
                    key_cert_sign=False,
                    crl_sign=False,
                    encipher_only=False,
                    decipher_only=False,
                ),
                critical=True,
            )
            .add_extension(
                x509.ExtendedKeyUsage(
                    [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
                ),
                critical=False,
            )
            .add_extension(x509.SubjectAlternativeName(_san([name, *hosts])), critical=False)
            .add_extension(
                x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), False
            )
            .sign(ca_key, hashes.SHA256())
        )
        _write_key(out / f"{name}.key", key)
        _write_cert(out / f"{name}.pem", cert)
        written.extend([out / f"{name}.pem", out / f"{name}.key"])

    leaf("router", router_hosts)
    connect = [f"tls/{_host_port(h)}" for h in router_hosts[:1]]
    for name in [*(vehicle_cn(v) for v in vehicles), *(gcs_cn(g) for g in gcs)]:
        leaf(name, ())
        path = out / f"{name}.json5"
        path.write_text(
            _json5(
                client_config(install, name, connect),
                f"{name}: client of the router over mutual TLS",
            )
        )
        written.append(path)
    path = out / "router.json5"
    path.write_text(
        _json5(
            router_config(install, swarm, vehicles, gcs),
            "the lab router: mutual TLS and access control",
        )
    )
    written.append(path)
    return written


def _host_port(host: str) -> str:
    try:
        if ipaddress.ip_address(host).version == 6:
            return f"[{host}]:{ROUTER_PORT}"
    except ValueError:
        pass
    return f"{host}:{ROUTER_PORT}"


def _json5(conf: dict[str, Any], what: str) -> str:
    return (
        f"// bandada swarm {what}.\n"
        "// Generated by `swarm-node certs make`; regenerate rather than edit (docs/security.md).\n"
        + json.dumps(conf, indent=2)
        + "\n"
    )


def parse_ids(text: str) -> list[int]:
    """'1,2,5-7' -> [1, 2, 5, 6, 7]"""
    ids: list[int] = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        lo, _, hi = part.partition("-")
        try:
            a, b = int(lo), int(hi or lo)
        except ValueError as exc:
            raise ValueError(f"bad id list {text!r}") from exc
        ids.extend(range(a, b + 1))
    return ids
