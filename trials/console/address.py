"""Where participants' phones reach the console: the address their questionnaire links and QR codes carry.

Served on loopback (127.0.0.1, localhost, ::1) only this laptop reaches the console, so its run pages say so and
name the command that lets phones in. Served on every address (0.0.0.0, ::) the links carry this laptop's address
on its network, found without sending anything; served on one address, that address. When no address is found,
the links carry the address the experimenter's browser used (its Host header).
"""

from __future__ import annotations

import ipaddress
import socket
from collections.abc import Callable
from dataclasses import dataclass

#: Addresses that listen on every interface.
WILDCARDS = ("0.0.0.0", "::", "")
#: A private-range address to point a UDP socket at: its connect picks the interface a route would use and sends nothing.
PROBE = ("10.255.255.255", 1)
#: The option of `trials serve` that lets phones on the lab's network in.
NETWORK_OPTION = "--host 0.0.0.0"


@dataclass(frozen=True)
class Reach:
    """How participants' phones reach a console served on `served_on` (`trials serve --host`): `host` for their links
    (None: the address the experimenter's browser used)."""

    served_on: str
    host: str | None

    @property
    def local_only(self) -> bool:
        """Served on loopback: only this laptop reaches the console, phones cannot."""
        return is_loopback(self.served_on)


#: A console served on this laptop only, as `trials serve` is by default.
LOOPBACK = Reach("127.0.0.1", None)


def is_loopback(host: str) -> bool:
    """Whether `host` is a loopback address or the name localhost."""
    if host.lower().rstrip(".") == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def _usable(address: str | None) -> bool:
    try:
        found = ipaddress.ip_address(address or "")
    except ValueError:
        return False
    return not (found.is_loopback or found.is_unspecified)


def network_address() -> str | None:
    """This machine's IPv4 address on its network (None when it has only loopback): the interface a UDP socket
    pointed at a private-range address would use (connecting a UDP socket sends no packet), else one its host name
    resolves to."""
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.connect(PROBE)
            found = probe.getsockname()[0]
    except OSError:
        found = None
    if _usable(found):
        return found
    try:
        named = [str(info[4][0]) for info in socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET)]
    except OSError:
        named = []
    return next((address for address in named if _usable(address)), None)


def participant_reach(served_on: str, found: Callable[[], str | None] = network_address) -> Reach:
    """How phones reach a console served on `served_on` (`trials serve --host`); `found` finds this machine's
    network address for a console served on every address."""
    if is_loopback(served_on):
        return Reach(served_on, None)
    if served_on in WILDCARDS:
        return Reach(served_on, found())
    return Reach(served_on, served_on.strip("[]"))


def url_host(host: str) -> str:
    """`host` as a URL writes it (an IPv6 address in brackets)."""
    return f"[{host}]" if ":" in host else host
