"""Where ``wbmp batch --ray`` runs: the address checked before use, and a local Ray on loopback.

* :func:`parse_address`: ``--ray ADDRESS`` must be ``auto``, ``host:port`` (a cluster's GCS, as
  ``ray start --head`` prints it) or ``ray://host:port`` (a Ray Client server); anything else is
  one line, exit 2, before any work.
* :func:`check_reachable`: the address (``auto`` first resolved the way Ray does it:
  ``RAY_ADDRESS``, else the cluster this machine last started or runs) must answer within
  :data:`CONNECT_TIMEOUT`: a TCP connection, and an HTTP/2 handshake (both a GCS and a Ray Client
  server speak gRPC). Nothing listening, a port that never answers, or a server of another kind
  (a web server) is one line naming the address, exit 2, instead of Ray's own retries (minutes,
  then a ``SystemExit``).
* :func:`loopback_only`: a local instance (``--ray`` without an address) and a cluster on this
  machine's loopback are used through 127.0.0.1 only: the node address is 127.0.0.1 (Ray
  otherwise replaces a loopback address by this machine's network address, and its processes
  listen there), no dashboard, no usage statistics sent. Every socket of such an instance
  listens on 127.0.0.1 (tests/wbmp/test_batch_ray.py checks it with ``ss``).

Ray is imported lazily (``pip install 'wbmp[ray]'``); this module imports it only to resolve
``auto`` and to switch it to loopback.
"""

from __future__ import annotations

import contextlib
import ipaddress
import os
import re
import socket
from collections.abc import Iterator
from dataclasses import dataclass

from wbmp.errors import CliError, ExitCode, one_line

#: How long the address gets to answer (TCP connection and HTTP/2 handshake) [s].
CONNECT_TIMEOUT = 5.0
LOOPBACK = "127.0.0.1"
#: Ray's switch between "a node reachable by others" (this machine's network address) and the
#: loopback address; read by Ray's processes from the environment, and by this one at its import.
CLUSTER_VARIABLE = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"
#: Environment of a loopback-only Ray: the processes it starts inherit it.
LOOPBACK_ENV = {CLUSTER_VARIABLE: "0", "RAY_USAGE_STATS_ENABLED": "0"}
#: Environment of this process while it drives Ray (Ray reads it at its import; :func:`driver`
#: sets the value it was read into as well).
DRIVER_ENV = {"RAY_DISABLE_FAILURE_SIGNAL_HANDLER": "1"}

_FORMS = "host:port (e.g. 127.0.0.1:6379), ray://host:port (a Ray Client server), or auto"
_HOSTNAME = re.compile(r"^(?=.{1,253}$)[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?"
                       r"(?:\.[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*$")
#: The client's first bytes of HTTP/2 (RFC 9113 §3.4): the preface, then an empty SETTINGS frame.
_H2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + b"\x00\x00\x00\x04\x00\x00\x00\x00\x00"
_H2_SETTINGS = 0x4


@dataclass(frozen=True, slots=True)
class RayAddress:
    """A checked ``--ray`` address.

    Attributes:
        text: As the user gave it.
        kind: ``auto``, ``gcs`` (host:port) or ``client`` (ray://host:port).
        host: The host (None for auto).
        port: The port (None for auto).
    """

    text: str
    kind: str
    host: str | None = None
    port: int | None = None

    @property
    def target(self) -> str:
        """What ``ray.init(address=...)`` gets."""
        if self.kind == "auto":
            return "auto"
        host = f"[{self.host}]" if self.host is not None and ":" in self.host else self.host
        return f"{'ray://' if self.kind == 'client' else ''}{host}:{self.port}"

    @property
    def on_loopback(self) -> bool:
        """True when the host is this machine's loopback (127.0.0.0/8, ::1, localhost)."""
        return self.host is not None and is_loopback(self.host)


def is_loopback(host: str) -> bool:
    """True for a loopback address or ``localhost``."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _refuse(text: str, why: str) -> CliError:
    return CliError(f"--ray {one_line(text, 200)!r}: {why}", ExitCode.USAGE)


def parse_address(text: str) -> RayAddress:
    """``--ray ADDRESS`` checked for its form (no network use).

    Raises:
        CliError: not ``auto``, ``host:port`` or ``ray://host:port`` (exit 2).
    """
    value = text.strip()
    if not value:
        raise _refuse(text, f"the address is empty; give {_FORMS}, or no value for a local instance")
    if value.lower() == "auto":
        return RayAddress(text=text, kind="auto")
    kind, rest = "gcs", value
    scheme, sep, tail = value.partition("://")
    if sep:
        if scheme.lower() != "ray":
            raise _refuse(text, f"unknown scheme {one_line(scheme, 40)!r}://; give {_FORMS}")
        kind, rest = "client", tail
    if rest.startswith("["):  # [IPv6]:port
        host, bracket, port_text = rest[1:].partition("]")
        if not bracket or not port_text.startswith(":"):
            raise _refuse(text, f"not an address; give {_FORMS}")
        port_text = port_text[1:]
    else:
        host, colon, port_text = rest.rpartition(":")
        if not colon:
            raise _refuse(text, f"no port; give {_FORMS}")
    if not port_text.isascii() or not port_text.isdigit() or len(port_text) > 5 or not 1 <= int(port_text) <= 65535:
        raise _refuse(text, f"the port {one_line(port_text, 20)!r} is not a number from 1 to 65535; give {_FORMS}")
    try:
        ipaddress.ip_address(host)
    except ValueError:
        if not _HOSTNAME.match(host):
            raise _refuse(text, f"the host {one_line(host, 80)!r} is not a host name or IP address; "
                                f"give {_FORMS}") from None
    return RayAddress(text=text, kind=kind, host=host, port=int(port_text))


def resolve_auto(address: RayAddress) -> RayAddress:
    """``auto`` as Ray resolves it (``RAY_ADDRESS``, else a cluster on this machine); another
    address as it is.

    Raises:
        CliError: no running cluster was found, or ``RAY_ADDRESS`` is not an address (exit 2).
    """
    if address.kind != "auto":
        return address
    given = os.environ.get("RAY_ADDRESS", "").strip()
    if given and given.lower() not in ("auto", "local"):
        try:
            return parse_address(given)
        except CliError as e:
            raise _refuse(address.text, f"RAY_ADDRESS {one_line(given, 200)!r} is not an address: give {_FORMS}") from e
    with loopback_only():  # Ray would turn a cluster on 127.0.0.1 into this machine's network address
        from ray._private.services import canonicalize_bootstrap_address

        try:
            found = canonicalize_bootstrap_address("auto")
        except Exception as e:  # noqa: BLE001 - ConnectionError (none found) or a damaged record of Ray's
            raise _refuse(address.text, "no running Ray cluster found on this machine (start one with `ray start "
                                        f"--head`, set RAY_ADDRESS, or give its address): {one_line(str(e), 200)}") from None
    if not found:
        raise _refuse(address.text, "no running Ray cluster found on this machine (start one with `ray start --head`, "
                                    "set RAY_ADDRESS, or give its address)")
    return parse_address(found)


def probe(host: str, port: int, timeout: float | None = None) -> str | None:
    """Why ``host:port`` is not a gRPC server (None when it answers the HTTP/2 handshake).

    Connects (TCP), sends the HTTP/2 client preface and waits for the server's SETTINGS frame,
    all within ``timeout`` [s] (default :data:`CONNECT_TIMEOUT`). Sends nothing else.
    """
    timeout = CONNECT_TIMEOUT if timeout is None else timeout
    try:
        conn = socket.create_connection((host, port), timeout=timeout)
    except TimeoutError:
        return f"no answer within {timeout:g} s"
    except OSError as e:
        return f"cannot connect ({e.strerror or e})"
    with conn:
        try:
            conn.settimeout(timeout)
            conn.sendall(_H2_PREFACE)
            head = b""
            while len(head) < 9:
                chunk = conn.recv(9 - len(head))
                if not chunk:
                    break
                head += chunk
        except TimeoutError:
            return f"connected, but no answer within {timeout:g} s"
        except OSError as e:
            return f"connected, but the connection failed ({e.strerror or e})"
    if len(head) < 9 or head[3] != _H2_SETTINGS:
        return "something answers, but it is not a Ray server (no gRPC handshake)"
    return None


def check_reachable(address: RayAddress, timeout: float | None = None) -> RayAddress:
    """The address (``auto`` resolved) after it answered as a gRPC server within ``timeout`` [s]
    (default :data:`CONNECT_TIMEOUT`).

    Raises:
        CliError: one line naming the address and what went wrong (exit 2).
    """
    resolved = resolve_auto(address)
    if resolved.host is None or resolved.port is None:  # pragma: no cover - resolve_auto gives host:port
        raise _refuse(address.text, f"not an address; give {_FORMS}")
    why = probe(resolved.host, resolved.port, timeout)
    if why is not None:
        shown = address.text if resolved is address else f"{address.text} ({resolved.target})"
        raise CliError(f"--ray {one_line(shown, 200)!r}: {why}; check that the cluster runs there "
                       "(`ray status`), or run without an address for a local instance", ExitCode.USAGE)
    return resolved


#: Longest path of a Unix socket (``sun_path`` less its NUL) [bytes].
_MAX_SOCKET_PATH = 107
#: What Ray adds below its temp folder for a socket: ``/ray/session_<date>_<time>_<us>_<pid>/sockets/plasma_store``.
_RAY_SOCKET_TAIL = len("/ray/session_2026-11-28_11-15-06_409362_4194304/sockets/plasma_store")


def check_local_temp() -> None:
    """A local instance can put its sockets in Ray's temp folder (``RAY_TMPDIR``, else ``TMPDIR``,
    else /tmp): a path too long for a Unix socket is one line before any work (exit 2), not
    Ray's traceback after the batch started.

    Raises:
        CliError: the folder's path is too long.
    """
    import sys

    base = os.environ.get("RAY_TMPDIR") or (os.environ.get("TMPDIR") if sys.platform.startswith("linux") else None)
    base = base or "/tmp"
    if len(os.fsencode(base)) + _RAY_SOCKET_TAIL > _MAX_SOCKET_PATH:
        raise CliError(f"--ray: Ray's temp folder {one_line(base, 200)!r} is too long for its sockets (at most "
                       f"{_MAX_SOCKET_PATH - _RAY_SOCKET_TAIL} bytes); set RAY_TMPDIR to a short folder, e.g. /tmp",
                       ExitCode.USAGE)


@contextlib.contextmanager
def _environment(values: dict[str, str]) -> Iterator[None]:
    saved = {name: os.environ.get(name) for name in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


@contextlib.contextmanager
def loopback_only() -> Iterator[None]:
    """Inside the block, Ray (this process and what it starts) keeps to 127.0.0.1: the
    variables of :data:`LOOPBACK_ENV` set, and Ray's switch read at its import turned off."""
    with _environment(LOOPBACK_ENV):
        import ray._private.ray_constants as constants

        flag = constants.ENABLE_RAY_CLUSTER
        constants.ENABLE_RAY_CLUSTER = False
        try:
            yield
        finally:
            constants.ENABLE_RAY_CLUSTER = flag


@contextlib.contextmanager
def driver(*, local: bool) -> Iterator[None]:
    """The environment of this process as Ray's driver: SIGTERM and SIGINT stay the CLI's
    (Ray's own failure-signal handler, which ends the process with SIGABRT after a SIGTERM the
    CLI handles, is not installed); with ``local``, :func:`loopback_only` too."""
    with _environment(DRIVER_ENV), loopback_only() if local else contextlib.nullcontext():
        import ray._private.ray_constants as constants

        flag = constants.RAY_DISABLE_FAILURE_SIGNAL_HANDLER  # read at Ray's import: set it here too
        constants.RAY_DISABLE_FAILURE_SIGNAL_HANDLER = True
        try:
            yield
        finally:
            constants.RAY_DISABLE_FAILURE_SIGNAL_HANDLER = flag
