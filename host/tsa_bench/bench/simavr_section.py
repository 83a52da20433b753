"""The ``simavr:`` section of a bench file: the firmware-in-the-loop rig's settings, checked.

Units: times in s unless a name says ms or us; voltages in V.

Contract: :func:`simavr_settings` reads ``bench.simavr`` into a :class:`SimavrSettings`
(paths resolved) or raises :class:`~tsa_bench.bench.errors.BenchConfigError` naming the
file and key; :func:`~tsa_bench.bench.parse_bench` calls it for every simavr bench, so a
bench file is checked whole without the emulator. The keys are documented in
:mod:`tsa_bench.simavr.launcher`, which starts the rig with these settings.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from tsa_bench.bench.errors import BenchConfigError
from tsa_bench.benchdata import BenchConfig

__all__ = ["PROJECT_FIRMWARE_DIR", "SimavrSettings", "simavr_settings"]


@dataclass(frozen=True)
class SimavrSettings:
    """The ``simavr:`` section of a bench file (paths already resolved)."""

    firmware_dir: Path
    heater_supply_V: float = 24.0
    lead_ms: float = 1000.0
    host_gone_ms: float = 4000.0
    realtime_factor: float = 0.0          # 0 = as fast as the host keeps up
    cs5513_conversion_us: float = 19125.0
    build: bool = True
    bootloader: str = "stock"
    enable_pull: str = "down"
    backdrive_steps_per_s: float = 16000.0
    ads_rate_error: float = 0.0
    twi_faults: tuple[str, ...] = ()
    rdy_cuts: tuple[str, ...] = ()        # the ALERT/RDY wire cut between T0[:T1] s (firmware/sim/ads1115.c)
    hang_at_s: float | None = None
    hang_masked: bool = False             # the injected hang runs with interrupts masked
    trace: bool = False

    @property
    def elf(self) -> Path:
        return self.firmware_dir / "build" / "tsa_bench.elf"

    @property
    def harness(self) -> Path:
        return self.firmware_dir / "build" / "tsa_simavr"

    @property
    def bootloader_elf(self) -> Path | None:
        return None if self.bootloader == "none" else self.firmware_dir / "build" / f"sim_boot_{self.bootloader}.elf"


_NUMBERS = {"heater_supply_V": (0.0, 100.0), "lead_ms": (1.0, 60000.0), "host_gone_ms": (10.0, 600000.0),
            "realtime_factor": (0.0, 1000.0), "cs5513_conversion_us": (1000.0, 1000000.0),
            "backdrive_steps_per_s": (0.0, 1e6), "ads_rate_error": (-0.5, 0.5)}
_CHOICES = {"bootloader": ("stock", "2011", "none"), "enable_pull": ("down", "up")}


#: The project's own firmware folder: the only one built unless the user trusts another.
PROJECT_FIRMWARE_DIR = Path(__file__).resolve().parents[3] / "firmware"


#: When this installation carries no firmware (a wheel: only the host program and configs/).
NO_FIRMWARE = (
    "{where}: this tsa-bench was installed without the firmware (a wheel carries only the host program): the "
    "simavr bench builds and runs the firmware from the source checkout, and so does flashing a Mega "
    "(`make -C firmware flash`). Get the checkout (git clone of the tsa-bench repository; its firmware/ "
    "folder), install it with `pip install -e .` there, and run from it. Without it you can still use the "
    "simulated bench (--bench sim.yaml, the default), a Mega flashed from a checkout (--port), and every "
    "analysis command")


def simavr_settings(bench: BenchConfig, *, trust_firmware_dir: bool = False) -> SimavrSettings:
    """The bench file's ``simavr:`` section; raise BenchConfigError naming file and key.

    ``firmware_dir`` is relative to the bench file's directory (default: the
    checkout's ``firmware/``). Because the launcher runs ``make`` in it, any other
    folder is refused unless ``trust_firmware_dir`` (``--trust-firmware-dir``).
    """
    where = f"{bench.path or '<bench>'}: simavr"
    data = dict(bench.simavr)
    allowed = {"firmware_dir", "build", *_NUMBERS, *_CHOICES}
    for key in data:
        if key not in allowed:
            raise BenchConfigError(f"{where}: unknown key '{key}' (allowed: {', '.join(sorted(allowed))})")
    base = Path(bench.path).resolve().parent if bench.path else Path.cwd()
    fw = data.pop("firmware_dir", None)
    if fw is None:
        firmware_dir = PROJECT_FIRMWARE_DIR
    elif isinstance(fw, str) and fw.strip() and "\x00" not in fw:
        firmware_dir = (base / fw).resolve()
    else:
        raise BenchConfigError(f"{where}: 'firmware_dir' must be a path, got {fw!r}")
    if not (firmware_dir / "Makefile").is_file() and not (PROJECT_FIRMWARE_DIR / "Makefile").is_file():
        raise BenchConfigError(NO_FIRMWARE.format(where=where))
    if firmware_dir != PROJECT_FIRMWARE_DIR.resolve() and not trust_firmware_dir:
        raise BenchConfigError(
            f"{where}: 'firmware_dir' {firmware_dir} is not this project's firmware folder "
            f"({PROJECT_FIRMWARE_DIR}); the simavr bench runs `make` there, so another folder is used only "
            "with --trust-firmware-dir")
    build = data.pop("build", True)
    if not isinstance(build, bool):
        raise BenchConfigError(f"{where}: 'build' must be true or false, got {build!r}")
    choices: dict[str, str] = {}
    for key, options in _CHOICES.items():
        if key in data:
            value = data.pop(key)
            if str(value) not in options:
                raise BenchConfigError(f"{where}: '{key}' must be one of {', '.join(options)}, got {value!r}")
            choices[key] = str(value)
    values: dict[str, float] = {}
    for key, value in data.items():
        lo, hi = _NUMBERS[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
            raise BenchConfigError(f"{where}: '{key}' must be a number in [{lo:g}, {hi:g}], got {value!r}")
        values[key] = float(value)
    return SimavrSettings(firmware_dir=firmware_dir, build=build, **values, **choices)  # type: ignore[arg-type]
