"""Before Ray connects to a cluster: is anything listening at the address? (issue 50: an
``--address`` naming no cluster made Ray retry for ever, and ignore SIGTERM for half a minute).

Ray's own connection to a GCS that is not there retries without a bound; a TCP connection to the
address with a timeout answers the question in at most :data:`PROBE_SECONDS`, and a refusal is one
line naming the address and the fix. ``auto`` (the address file of a local cluster) is left to Ray,
which answers that at once.
"""

from __future__ import annotations

import socket

from .._errors import ConfigError

__all__ = ["PROBE_SECONDS", "probe_address"]

#: seconds to wait for the cluster's port to accept a connection
PROBE_SECONDS = 10.0
_DEFAULT_PORTS = {"ray://": 10001, "": 6379}


def _host_port(address: str) -> tuple[str, int] | None:
    text = address.strip()
    scheme = "ray://" if text.startswith("ray://") else ""
    if scheme == "" and "://" in text:
        return None  # another scheme (a Ray Client proxy, anyscale://...): Ray's own answer
    rest = text[len(scheme):].split("/", 1)[0]
    if not rest or rest == "auto" or rest.startswith("localhost:auto"):
        return None
    host, sep, port = rest.rpartition(":")
    if not sep:
        host, port = rest, str(_DEFAULT_PORTS[scheme])
    host = host.strip("[]")  # [::1]:6379
    if not port.isdigit() or not 0 < int(port) < 65536 or not host:
        raise ConfigError(f"the Ray address {address!r} is not HOST:PORT (e.g. 10.0.0.5:6379 or ray://head:10001) "
                          "nor 'auto'; give the address `ray start --head` printed")
    return host, int(port)


def probe_address(address: str, timeout: float = PROBE_SECONDS) -> None:
    """A ConfigError in one line when nothing accepts a TCP connection at ``address`` within
    ``timeout`` seconds (no cluster there); silent when something does, or for ``auto``."""
    where = _host_port(address)
    if where is None:
        return
    host, port = where
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return
    except OSError as exc:
        why = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or type(exc).__name__)
        raise ConfigError(f"no Ray cluster answers at {address!r} ({host}:{port}: {why} within {timeout:g} s); start "
                          "one (`ray start --head`), check the address (`ray status` on the head node), or drop "
                          "--address (and unset RAY_ADDRESS) to run here") from None
