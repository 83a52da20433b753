"""Latched device faults in words: what latched, when, what clears it, what to do.

Units: time in s.

Contract: :data:`RECOVERY` gives, for every fault of the catalogue, what a person does
before the fault is cleared (firmware/README.md "Faults and their recovery" and
docs/rig.md "When the rig faults" say the same). :func:`latched_text` describes a fault
a QUEUE_STATUS reports: its name, how old it is as far as the device lets the host tell
(the protocol carries no time of the fault; a released motor means it is older than
the identity's ``fault_release_ms``), and the recovery. A latched fault is cleared by
CLEAR_QUEUE once its cause is gone; every tsa-bench command that opens the rig (``run``,
``check``, ``zero``, ``jog``, ``calibrate``) sends it after saying so (:data:`CLEARS`).
"""

from __future__ import annotations

from tsa_bench.protocol import msg

#: What clears a latched fault, named in every message that reports one.
CLEARS = ("the next `tsa-bench check`, `zero` or `run` clears it (CLEAR_QUEUE) after saying so, "
          "once its cause is gone")

#: fault name -> what a person does before clearing it.
RECOVERY: dict[str, str] = {
    "watchdog": "the host fell silent while the device was busy (a killed or stalled program, a pulled cable, "
                "Ctrl-C while sampling): nothing to repair; check the twist before the next run",
    "twist_limit": "the motor went beyond the twist limits: look at the TSA, untwist it by hand if needed and "
                   "declare its twist with `tsa-bench zero --turns N`",
    "heater_limit": "a heater voltage above the device's maximum was asked for: check the protocol's and the "
                    "bench file's heater limits",
    "position_sensor": "the ADS1115 did not answer on I2C: check its wiring (SDA 20, SCL 21, 5 V, GND) and "
                       "`tsa-bench check` the sensors",
    "resistance_adc": "the CS5513 conversion did not finish: check its SPI wiring and the sense current, then "
                      "`tsa-bench check` the sensors",
    "overtemperature": "the heater was on longer than its duty limit allows: let the string cool for a few "
                       "minutes before heating again",
}


def fault_name(code: int) -> str:
    """The catalogue name of a fault code (the number when the catalogue has none)."""
    try:
        return msg.Fault(code).name.lower()
    except ValueError:
        return f"fault {code}"


def latched_text(status: msg.QueueStatus, identity: msg.Identity | None = None) -> str:
    """One line: what is latched, since when, what to do, what clears it."""
    name = fault_name(status.fault)
    if status.state & msg.DeviceState.MOTOR_RELEASED:
        release = f" over {identity.fault_release_ms / 1000:g} s" if identity and identity.fault_release_ms else ""
        when = f"latched{release} ago (the motor has since been released: position unknown)"
    elif identity is not None and identity.fault_release_ms:
        when = f"latched less than {identity.fault_release_ms / 1000:g} s ago (the motor is still held)"
    else:
        when = "latched"
    recovery = RECOVERY.get(name, "see firmware/README.md, Faults and their recovery")
    return f"device fault {name} {when}; {recovery}; {CLEARS}"
