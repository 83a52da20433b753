"""Which serial ports are there, and which is likely the bench's Arduino Mega.

Contract: :func:`list_ports` lists the serial ports pyserial finds (USB vendor and
product ids, serial number, description), each with :func:`likely_board`'s guess;
:func:`probe` opens one port and tries the tsa-bench handshake, reporting the
firmware version and whether the device is a simulation, or why it did not answer.
Probing opens the port, which resets a Mega (DTR) and may disturb another device, so
it is only done when asked.
"""

from __future__ import annotations

from dataclasses import dataclass

from tsa_bench.benchdata import BenchConfig

#: (vendor id, product id) -> board: the genuine Arduino Mega 2560 boards.
MEGA_IDS: dict[tuple[int, int], str] = {
    (0x2341, 0x0010): "Arduino Mega 2560",
    (0x2341, 0x0042): "Arduino Mega 2560 R3",
    (0x2341, 0x0242): "Arduino Mega 2560 R3 (bootloader)",
    (0x2A03, 0x0010): "Arduino Mega 2560 (arduino.org)",
    (0x2A03, 0x0042): "Arduino Mega 2560 R3 (arduino.org)",
}
#: USB-serial bridges found on Mega clones: a Mega perhaps, not for sure.
CLONE_BRIDGES: dict[tuple[int, int], str] = {
    (0x1A86, 0x7523): "CH340 USB-serial (common on Mega clones)",
    (0x1A86, 0x55D4): "CH9102 USB-serial (some Mega clones)",
    (0x0403, 0x6001): "FTDI FT232R USB-serial (older Megas and clones)",
    (0x10C4, 0xEA60): "CP210x USB-serial (some Mega clones)",
}


@dataclass(frozen=True)
class PortInfo:
    """One serial port as the operating system describes it."""

    device: str
    description: str = ""
    vid: int | None = None
    pid: int | None = None
    serial_number: str | None = None
    manufacturer: str | None = None

    @property
    def usb_id(self) -> str:
        return "" if self.vid is None or self.pid is None else f"{self.vid:04X}:{self.pid:04X}"


def likely_board(port: PortInfo) -> tuple[int, str]:
    """(likelihood 2 = a Mega, 1 = perhaps, 0 = no sign, text) from the USB ids."""
    key = (port.vid, port.pid)
    if key in MEGA_IDS:
        return 2, MEGA_IDS[key]
    if key in CLONE_BRIDGES:
        return 1, CLONE_BRIDGES[key]
    if "mega" in (port.description or "").lower():
        return 2, port.description
    if port.vid == 0x2341 or port.vid == 0x2A03:
        return 1, "an Arduino board (not a Mega's USB id)"
    return 0, ""


def list_ports() -> list[PortInfo]:
    """The serial ports of this machine, likely Megas first."""
    from serial.tools import list_ports as lp

    found = [PortInfo(p.device, p.description or "", p.vid, p.pid, p.serial_number, p.manufacturer)
             for p in lp.comports()]
    return sorted(found, key=lambda p: (-likely_board(p)[0], p.device))


@dataclass(frozen=True)
class ProbeResult:
    device: str
    ok: bool
    text: str


def probe(device: str, bench: BenchConfig, boot_timeout_s: float | None = None) -> ProbeResult:
    """Try the handshake on ``device`` (see the module contract)."""
    from tsa_bench.device import DeviceError
    from tsa_bench.rig.link import RigError, open_link

    try:
        with open_link(device, bench, boot_timeout_s=boot_timeout_s) as link:
            ident = link.identity
            kind = "a simulated device" if link.simulated else "a tsa-bench device"
            return ProbeResult(device, True, f"{kind}, firmware {ident.fw_major}.{ident.fw_minor}.{ident.fw_patch}, "
                                             f"protocol v{ident.protocol_version}, catalogue matches this host")
    except (RigError, DeviceError) as exc:   # a stall mid-handshake too: one line, the next port probed
        return ProbeResult(device, False, str(exc))
