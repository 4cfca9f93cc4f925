"""The documented secure bus (deploy/zenoh: mutual TLS, access control by certificate) end to end,
every node a separate process on loopback, and the attacks it stops; the same attacks on a bus
without it, where they succeed.

Certificates come from ``deploy/zenoh/make-certs.sh`` (openssl) into the test's directory; the
configuration files are the ones in ``deploy/zenoh`` with their certificate directory
replaced, and the endpoints given on the command line (``--listen``/``--connect`` override the
files'). A rig's certificate names the rig (``rig-01``, ``rig-02``); the router's access control
lets it put only that rig's sample and config.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import time
from pathlib import Path

import orjson
import pytest
import zenoh

import helpers
from helpers import CLI, health_bytes, sample_bytes, wait_for
from hydromon.bus.session import JSON, free_tcp_endpoint, open_session
from hydromon.store.mcap_read import read_recording

ROOT = Path(__file__).resolve().parents[2]
DEPLOY = ROOT / "deploy" / "zenoh"
ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}
RIGS = ("rig-01", "rig-02")
FORGED_SEQ = 10**6  # a verdict no monitor sent for these rigs
GHOST = "ghost-rig"  # a rig that does not exist
BLOCK = zenoh.CongestionControl.BLOCK

pytestmark = [pytest.mark.network,
              pytest.mark.skipif(shutil.which("openssl") is None, reason="the certificates are made with openssl")]


class Procs(helpers.Procs):
    """Node processes (``helpers.Procs``), and this process's own sessions, closed first by
    :meth:`close` (open sessions would hang its exit)."""

    def __init__(self, directory: Path):
        super().__init__(directory)
        self.sessions: list[zenoh.Session] = []

    def session(self, s: zenoh.Session) -> zenoh.Session:
        self.sessions.append(s)
        return s

    def alive(self):
        """Every node but ``watch`` (which runs once and ends) is still running."""
        for name, p in self.procs.items():
            if p.poll() is not None and name not in ("watch",):
                raise AssertionError(f"{name} exited ({p.returncode}): {self.log(name)[-2000:]}")

    def close(self) -> None:
        for s in self.sessions:
            try:
                s.close()
            except zenoh.ZError:
                pass
        super().close()


def make_certs(directory: Path, *rigs: str) -> Path:
    subprocess.run(["sh", str(DEPLOY / "make-certs.sh"), str(directory), "router.plant", *rigs],
                   check=True, capture_output=True, timeout=60)
    return directory


def config(tmp: Path, name: str, certs: Path, cert: str | None = None) -> Path:
    """deploy/zenoh/NAME.json5 with its certificates in ``certs`` (a rig's: ``cert``)."""
    text = (DEPLOY / f"{name}.json5").read_text().replace("/etc/hydromon/tls/", f"{certs}/")
    if cert is not None:
        text = text.replace(f"{certs}/rig.", f"{certs}/{cert}.")
    path = tmp / f"{cert or name}-{certs.name}.json5"
    path.write_text(text)
    return path


def client(conf: Path, ep: str) -> zenoh.Session:
    """A session of this process from a client configuration, connecting to ``ep``."""
    return open_session(connect=[ep], config_file=conf)


def start_router(procs: Procs, *args: str) -> str:
    """A ``hydromon router`` on a free loopback port (another if it was taken); its endpoint."""
    for attempt in range(5):
        port = free_tcp_endpoint().rsplit(":", 1)[1]
        proto = "tls" if "--zenoh-config" in args else "tcp"
        ep = f"{proto}/127.0.0.1:{port}"
        p = procs.start("router", *args, "--listen", ep)
        wait_for(lambda: "listening on" in procs.log("router") or p.poll() is not None, 60, "the router")
        if p.poll() is None:
            return ep
    raise AssertionError(f"no router came up: {procs.log('router')[-2000:]}")


def fleet_file(tmp: Path, rig: str, group: int) -> Path:
    path = tmp / f"fleet-{rig}.json"
    path.write_text(json.dumps({"rigs": [{"id": rig, "table4": group}]}))
    return path


def forged_health(rig: str) -> bytes:
    return health_bytes(FORGED_SEQ, 1.0)


def attack(procs: Procs, ep: str, conf: Path | None) -> dict:
    """What a rig-01 client tries: put a verdict, another rig's sample and config, answer health
    queries with forged verdicts (for rig-01 and a rig that does not exist), read everything."""
    s = procs.session(client(conf, ep) if conf is not None else open_session("client", connect=[ep]))
    seen = []  # what reaches it from other nodes
    sub = s.declare_subscriber("hydro/**", lambda m: seen.append(str(m.key_expr)), allowed_origin=zenoh.Locality.REMOTE)
    q = s.declare_queryable("hydro/rig/*/health", lambda query: (
        query.reply("hydro/rig/rig-01/health", forged_health("rig-01"), encoding=JSON),
        query.reply(f"hydro/rig/{GHOST}/health", forged_health(GHOST), encoding=JSON)))
    time.sleep(0.5)
    for _ in range(5):
        s.put("hydro/rig/rig-01/health", forged_health("rig-01"), encoding=JSON, congestion_control=BLOCK)
        s.put(f"hydro/rig/{GHOST}/health", forged_health(GHOST), encoding=JSON, congestion_control=BLOCK)
        s.put("hydro/rig/rig-02/sample", sample_bytes(7, 1.0, ug=0.5, x5=1e-3), encoding=JSON, congestion_control=BLOCK)
        s.put("hydro/rig/rig-02/config", b'{"p_s": 1.0}', encoding=JSON, congestion_control=BLOCK)
        time.sleep(0.1)
    return {"session": s, "seen": seen, "keep": (sub, q)}


FORGED = {forged_health("rig-01"), sample_bytes(7, 1.0, ug=0.5, x5=1e-3), b'{"p_s": 1.0}'}


def watch_once(ep: str, conf: Path | None) -> dict:
    args = CLI + ["watch", "--once", "--json", "--wait", "3", "--connect", ep]
    args += ["--zenoh-config", str(conf)] if conf is not None else ["--mode", "client"]
    out = subprocess.run(args, capture_output=True, text=True, timeout=60, env=ENV)
    assert out.returncode in (0, 1), out.stderr
    return orjson.loads(out.stdout) if out.stdout.strip() else {"rigs": {}}


@pytest.mark.timeout(300)
def test_the_documented_secure_bus_works_end_to_end_and_stops_every_attack(tmp_path):
    certs = make_certs(tmp_path / "tls", *RIGS)
    other = make_certs(tmp_path / "other-ca", *RIGS)  # a CA the router does not trust, same names
    procs = Procs(tmp_path)
    try:
        ep = start_router(procs, "router", "--zenoh-config", str(config(tmp_path, "router", certs)))
        viewer = procs.session(client(config(tmp_path, "viewer", certs), ep))
        observer = procs.session(client(config(tmp_path, "recorder", certs), ep))  # a recorder's: reads everything
        health, everything = [], []
        viewer.declare_subscriber("hydro/rig/*/health", lambda m: health.append((str(m.key_expr), m.payload.to_bytes())))
        observer.declare_subscriber("hydro/**", lambda m: everything.append((str(m.key_expr), m.payload.to_bytes())))
        procs.start("monitor", "monitor", "--zenoh-config", str(config(tmp_path, "monitor", certs)), "--connect", ep,
                    "--node", "m1", "--stale-after", "600")
        procs.start("record", "record", "--zenoh-config", str(config(tmp_path, "recorder", certs)), "--connect", ep,
                    "--out", str(tmp_path / "rec.mcap"))
        wait_for(lambda: any(r.ok is not None for r in viewer.liveliness().get("hydro/monitor/m1", timeout=1.0)),
                 240, "the monitor's liveliness token", alive=procs.alive)
        wait_for(lambda: "writing" in procs.log("record"), 60, "the recorder", alive=procs.alive)
        for i, rig in enumerate(RIGS):
            procs.start(rig, "sim", "--zenoh-config", str(config(tmp_path, "rig", certs, rig)), "--connect", ep,
                        "--fleet", str(fleet_file(tmp_path, rig, i + 1)), "--rate", "2")
        wait_for(lambda: {k for k, _ in health} >= {f"hydro/rig/{r}/health" for r in RIGS}, 240,
                 "the monitor's verdicts on both rigs", alive=procs.alive)

        # a rig's certificate: only its own sample and config
        att = attack(procs, ep, config(tmp_path, "rig", certs, "rig-01"))
        # a certificate of another CA, no certificate, plain TCP: refused at once (a client's
        # session does not open), whatever the certificate's name
        no_cert = tmp_path / "no-cert.json5"
        no_cert.write_text(config(tmp_path, "rig", certs, "rig-01").read_text().replace("enable_mtls: true",
                                                                                          "enable_mtls: false"))
        for opener in (lambda: client(config(tmp_path, "rig", other, "rig-01"), ep),
                       lambda: client(config(tmp_path, "monitor", other), ep),
                       lambda: client(no_cert, ep),
                       lambda: open_session("client", connect=[ep.replace("tls/", "tcp/")])):
            t0 = time.monotonic()
            try:
                procs.session(opener())
            except ConnectionError as exc:
                assert "cannot open the zenoh session" in str(exc) and time.monotonic() - t0 < 10
                print(f"refused in {time.monotonic() - t0:.3f} s: {str(exc)[-80:]}")
            else:
                pytest.fail("a client the router must refuse opened its session")
        # a peer with an untrusted certificate opens a session (zenoh retries in silence), and reaches no one
        peer = tmp_path / "peer-other-ca.json5"
        peer.write_text(config(tmp_path, "rig", other, "rig-01").read_text().replace('mode: "client"', 'mode: "peer"'))
        p = procs.session(open_session(connect=[ep], config_file=peer))
        p.put("hydro/rig/rig-01/health", forged_health("rig-01"))
        time.sleep(0.5)
        assert list(p.info.routers_zid()) == [] and list(p.info.peers_zid()) == []
        # the foreign rig as a node: one error line, exit 1
        bad = subprocess.run(CLI + ["sim", "--zenoh-config", str(config(tmp_path, "rig", other, "rig-01")),
                                    "--connect", ep, "--fleet", str(fleet_file(tmp_path, "rig-01", 1))],
                             capture_output=True, text=True, timeout=120, env=ENV)
        assert bad.returncode == 1 and "hydromon sim: error: cannot open the zenoh session" in bad.stderr, bad.stderr

        doc = watch_once(ep, config(tmp_path, "viewer", certs))
        time.sleep(1.0)  # what was let through would have arrived by now
        assert sorted(doc["rigs"]) == sorted(RIGS), doc  # no ghost rig
        assert all(h["seq"] != FORGED_SEQ for h in doc["rigs"].values()) and doc["invalid"] == 0
        assert not [p for _, p in everything if p in FORGED]
        assert not [p for _, p in health if p in FORGED]
        assert not any(k.endswith(f"/{GHOST}/health") for k, _ in everything)
        assert att["seen"] == []  # a rig reads nothing
        assert procs.stop("record") == 0, procs.log("record")
        recorded = [(k, p) for k, p, _, _ in read_recording(tmp_path / "rec.mcap")]
        keys = {k for k, _ in recorded}
        assert {f"hydro/rig/{r}/{leaf}" for r in RIGS for leaf in ("sample", "config", "health")} <= keys
        assert not [p for _, p in recorded if p in FORGED] and not [k for k in keys if GHOST in k]
    finally:
        procs.close()


@pytest.mark.timeout(120)
def test_the_same_attacks_succeed_on_a_bus_without_the_configuration(tmp_path):
    procs = Procs(tmp_path)
    try:
        ep = start_router(procs, "router")
        observer = procs.session(open_session("client", connect=[ep]))
        everything = []
        observer.declare_subscriber("hydro/**", lambda m: everything.append((str(m.key_expr), m.payload.to_bytes())))
        time.sleep(0.5)
        att = attack(procs, ep, None)  # no certificate at all
        doc = watch_once(ep, None)
        wait_for(lambda: FORGED <= {p for _, p in everything}, 10, "the forged messages")
        assert GHOST in doc["rigs"] and doc["rigs"]["rig-01"]["seq"] == FORGED_SEQ  # forged verdicts shown
        observer.put("hydro/rig/rig-02/sample", sample_bytes(8, 1.0))
        wait_for(lambda: "hydro/rig/rig-02/sample" in att["seen"], 10, "another node's sample at the attacker")
        assert any(k.endswith(f"/{GHOST}/health") for k, _ in everything)
    finally:
        procs.close()
