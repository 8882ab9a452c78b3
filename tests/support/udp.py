"""Test support for loopback UDP: free consecutive ports, and subprocesses that keep Ctrl-C."""

from __future__ import annotations

import signal
import socket


def free_ports(n: int) -> int:
    """A base port such that base .. base+n-1 are free UDP ports on 127.0.0.1."""
    for _ in range(100):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.bind(("127.0.0.1", 0))
            base = probe.getsockname()[1]
        if base + n > 65535:
            continue
        socks = []
        try:
            for p in range(base, base + n):
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                socks.append(s)
                s.bind(("127.0.0.1", p))
            return base
        except OSError:
            continue
        finally:
            for s in socks:
                s.close()
    raise RuntimeError(f"no {n} consecutive free UDP ports")


def default_sigint() -> None:
    """preexec_fn for subprocesses: restore SIGINT, which a background shell may ignore."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
