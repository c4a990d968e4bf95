"""Ray for ``wbmp batch`` on this machine keeps to 127.0.0.1, and a cluster joined by address.

A real local instance is started the way ``wbmp batch --ray`` starts one
(:func:`wbmp.batch.raynet.loopback_only`, node address 127.0.0.1, no dashboard): its node
address is 127.0.0.1 and every TCP/UDP socket its processes hold open for listening is bound to
the loopback (read from ``/proc``, independently of Ray). Its GCS answers the address probe. Then a
real ``wbmp batch --ray 127.0.0.1:PORT`` (another process) joins it by that address and plans an
item on it. The form checks of :func:`~wbmp.batch.raynet.parse_address` have their own cases.
"""

from __future__ import annotations

import ipaddress
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.badinput.conftest import REPO
from wbmp.batch import raynet
from wbmp.batch.backends import local_pythonpath
from wbmp.errors import CliError


@pytest.mark.parametrize(("text", "kind", "target", "loopback"), [
    ("auto", "auto", "auto", False),
    (" AUTO ", "auto", "auto", False),
    ("127.0.0.1:6379", "gcs", "127.0.0.1:6379", True),
    ("localhost:1", "gcs", "localhost:1", True),
    ("head-node.cluster.example:6379", "gcs", "head-node.cluster.example:6379", False),
    ("ray://10.0.0.2:10001", "client", "ray://10.0.0.2:10001", False),
    ("RAY://127.0.0.2:10001", "client", "ray://127.0.0.2:10001", True),
    ("[::1]:6379", "gcs", "[::1]:6379", True),
    ("ray://[fe80::1]:65535", "client", "ray://[fe80::1]:65535", False),
])
def test_addresses_of_each_form_are_parsed(text, kind, target, loopback):
    """auto, host:port and ray://host:port (IPv4, IPv6 in brackets, host names); the target is
    what Ray gets, and a loopback host is told apart (Ray is kept on loopback for it)."""
    address = raynet.parse_address(text)
    assert (address.kind, address.target, address.on_loopback) == (kind, target, loopback)


@pytest.mark.parametrize("text", ["", " ", "6379", ":6379", "host:", "host:port", "host:-1", "host:1:2",
                                  "ray:/host:1", "tcp://host:1", "ho st:1", "-host:1", "host-:1", "[::1]6379",
                                  "a" * 300 + ":1", "host:000065536"])
def test_addresses_of_other_forms_are_refused(text):
    """Anything else is a CliError (exit 2) that names the address as given."""
    with pytest.raises(CliError) as info:
        raynet.parse_address(text)
    assert info.value.code == 2 and "--ray" in str(info.value) and "\n" not in str(info.value)


def _socket_inodes(pids: set[int]) -> set[str]:
    inodes = set()
    for pid in pids:
        try:
            fds = os.listdir(f"/proc/{pid}/fd")
        except OSError:
            continue
        for fd in fds:
            try:
                target = os.readlink(f"/proc/{pid}/fd/{fd}")
            except OSError:
                continue
            if target.startswith("socket:["):
                inodes.add(target[8:-1])
    return inodes


def _address(hex_text: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    """An address of /proc/net/{tcp,udp}{,6}: 32-bit words in host (little-endian) order."""
    raw = bytes.fromhex(hex_text)
    words = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
    return ipaddress.ip_address(words)


def _bound(pids: set[int]) -> list[tuple[str, int]]:
    """(address, port) of every listening TCP socket and bound UDP socket the processes hold."""
    inodes = _socket_inodes(pids)
    found = []
    for table, listening in (("tcp", "0A"), ("tcp6", "0A"), ("udp", None), ("udp6", None)):
        try:
            lines = Path(f"/proc/net/{table}").read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            local, state, inode = fields[1], fields[3], fields[9]
            if inode in inodes and (listening is None or state == listening):
                host, port = local.split(":")
                found.append((str(_address(host)), int(port, 16)))
    return found


def _descendants(pid: int) -> set[int]:
    parents = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                parents[int(entry)] = int(Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()[1])
            except OSError:
                continue
    found, frontier = set(), [pid]
    while frontier:
        parent = frontier.pop()
        for child, ppid in parents.items():
            if ppid == parent and child not in found:
                found.add(child)
                frontier.append(child)
    return found


def _loopback(address: str) -> bool:
    ip = ipaddress.ip_address(address)
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped
    return ip.is_loopback


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="reads sockets from Linux's /proc")
def test_a_local_instance_keeps_to_loopback_and_a_batch_joins_it_by_address(tmp_path, monkeypatch):
    """Node address 127.0.0.1; every socket of the instance bound to the loopback (none to
    0.0.0.0 or this machine's network address); its GCS answers the probe; ``wbmp batch --ray
    127.0.0.1:PORT`` plans an item on it (record: ok, backend ray, a worker of this machine)."""
    ray = pytest.importorskip("ray", reason="ray is not installed (pip install 'wbmp[ray]')")
    monkeypatch.setenv("PYTHONPATH", local_pythonpath())  # the instance's workers import wbmp
    with raynet.loopback_only():
        ray.init(num_cpus=1, include_dashboard=False, _node_ip_address=raynet.LOOPBACK, log_to_driver=False,
                 logging_level="ERROR", configure_logging=True)
        try:
            assert [node["NodeManagerAddress"] for node in ray.nodes()] == ["127.0.0.1"]
            host, _, port = ray.get_runtime_context().gcs_address.rpartition(":")
            assert host == "127.0.0.1"
            assert raynet.probe(host, int(port)) is None  # a real gRPC server answers the handshake

            @ray.remote(num_cpus=1)
            def where() -> str:  # a worker process started, and its own sockets counted below
                return ray.util.get_node_ip_address()

            assert ray.get(where.remote(), timeout=120) == "127.0.0.1"
            bound = _bound(_descendants(os.getpid()) | {os.getpid()})
            assert len(bound) >= 3, bound  # at least the GCS, the raylet and a worker
            assert [a for a in bound if not _loopback(a[0])] == []

            items = tmp_path / "items.jsonl"
            items.write_text(json.dumps({"id": "squat", "instruction": "squat"}) + "\n")
            out = tmp_path / "lib"
            proc = subprocess.run([sys.executable, "-m", "wbmp.cli", "batch", str(items), "--out-dir", str(out),
                                   "--no-sim", "--workers", "1", "--quiet", "--ray", f"127.0.0.1:{port}"],
                                  env={**os.environ, "PYTHONPATH": str(REPO)}, capture_output=True, text=True,
                                  timeout=600)
            assert proc.returncode == 0, proc.stderr
            record = json.loads((out / "index.jsonl").read_text())
            assert (record["status"], record["backend"], record["motion"]) == ("ok", "ray", "squat__talos.npz")
            assert (out / "squat__talos.npz").is_file()
        finally:
            ray.shutdown()
    assert not ray.is_initialized()
