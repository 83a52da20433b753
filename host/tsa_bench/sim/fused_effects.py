"""What each library effect and form contributes to the fused plant kernel (:mod:`tsa_bench.sim.fused`).

Units: as :mod:`tsa_bench.sim.plant` (s, turns, V, g/N, mm, ohm, degC).

Contract: ``SNIPPETS[name](snip, effect, prefix, ref)`` fills a :class:`Snip` with the
effect's parameters (read once from ``ref``, the effect in the factory, ``E[i]``), its
memory (loaded from and exported to the effect's attributes), quantities that change only
with the load, and its lines of the per-sample body. The body does what the effect's
``apply`` does on the plant's locals (``turns_cmd``, ``turns``, ``dt``, ``moving``,
``volts``, ``T``, ``L``, ``kf``, ``hs``, ``te``, ``x``, ``R``, ``load_g``, ``load_N``...),
with the same floating-point operations in the same order and the same random draws.
An effect whose parameters make it a no-op emits no body (each says why that is exact).
``random.gauss`` is inlined only when this Python's is the two-draw form written here
(checked at import), else called.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable
from typing import Any

#: resistance_hysteresis with at most this many play operators is unrolled into scalars
UNROLL_OPERATORS = 32


def _gauss_inline_matches() -> bool:
    """Whether this Python's ``random.gauss`` is the two-draw Box-Muller form inlined below."""
    a, b = random.Random(20240611), random.Random(20240611)
    nxt = None
    for sigma in (0.05, 0.001, 1.0, 3.5, 0.05):
        z = nxt
        nxt = None
        if z is None:
            x2pi = b.random() * (2.0 * math.pi)
            g2rad = math.sqrt(-2.0 * math.log(1.0 - b.random()))
            z = math.cos(x2pi) * g2rad
            nxt = math.sin(x2pi) * g2rad
        if a.gauss(0.0, sigma) != 0.0 + z * sigma:
            return False
    return a.random() == b.random()


INLINE_GAUSS = _gauss_inline_matches()


class Snip:
    """What one effect contributes: parameters, memory, per-load lines and body lines."""

    def __init__(self) -> None:
        self.params: list[tuple[str, str]] = []      # (var, expression on E[i])
        self.memory: list[tuple[str, str]] = []      # (var, attribute of E[i]) loaded and exported
        self.cells: list[tuple[str, str]] = []       # (var, initial expression) persistent, not exported
        self.load_lines: list[str] = []              # extra factory lines (after params and memory)
        self.export_lines: list[str] = []            # extra export lines
        self.perload: list[str] = []                 # lines run at set_load (and at build)
        self.perload_vars: list[str] = []
        self.body: list[str] = []
        self.E = ""                                  # the effect in the factory: "E[i]"


def _gauss_lines(var: str, sigma: str, target: str, p: str) -> list[str]:
    """``target += rng.gauss(0.0, sigma)`` with the draw inlined (or called if not inlinable)."""
    if not INLINE_GAUSS:
        return [f"{target} += {p}gauss(0.0, {sigma})"]
    return [f"z = {p}gnext",
            "if z is None:",
            f"    x2pi = {p}rnd() * GAUSS_TWOPI",
            f"    g2rad = sqrt(-2.0 * log(1.0 - {p}rnd()))",
            "    z = cos(x2pi) * g2rad",
            f"    {p}gnext = sin(x2pi) * g2rad",
            "else:",
            f"    {p}gnext = None",
            f"{target} += 0.0 + z * {sigma}"]


def length_expr(lines: list[str], out: str, length: str, turns: str, growth: bool | str, ind: str = "") -> None:
    """Lines setting ``out`` to :func:`~tsa_bench.sim.effects.tsa_length_mm` (same operations)."""
    lines.append(f"{ind}theta_r = TWO_PI * {turns} * r0")
    cubic = ["c = theta_r * theta_r * L0",
             f"if c <= 0.0 or {length} <= 0.0:",
             f"    {out} = {length}",
             "else:",
             f"    arg = NEG15S3 * c / ({length} * {length} * {length})",
             f"    {out} = {length} / SQRT3 if arg <= -1.0 else TWO_S3 * {length} * cos(acos(arg) / 3.0)"]
    plain = [f"x2 = {length} * {length} - theta_r * theta_r",
             f"fl = {length} / SQRT3",
             "if x2 > 0.0:",
             "    sq = sqrt(x2)",
             f"    {out} = fl if fl > sq else sq",
             "else:",
             f"    {out} = fl"]
    if growth is True:
        lines += [ind + s for s in cubic]
    elif growth is False:
        lines += [ind + s for s in plain]
    else:
        lines.append(f"{ind}if {growth}:")
        lines += [ind + "    " + s for s in cubic]
        lines.append(f"{ind}else:")
        lines += [ind + "    " + s for s in plain]


# -- one function per effect: fills a Snip (p: the effect's variable prefix, e: "E[i]") --------

def _missed_steps(s: Snip, e: Any, p: str, E: str) -> None:
    s.params.append((f"{p}hold", f"{E}.params.holding_torque_Nm"))
    s.memory.append((f"{p}lost", "lost_turns"))
    # F |dX/dtheta| <= F theta r0^2 L0 / X^2 <= 3 F theta r0^2 L0 / L^2 (radius growth; without it
    # F theta r0^2 / X <= sqrt(3) F theta r0^2 / L) since X >= L / sqrt(3): when that bound, with a
    # margin far above rounding, is within the holding torque, so is the torque the chain computes
    s.body += [f"want = turns_cmd - {p}lost",
               f"if L > 0.0 and (abs(want) * tqb_rg <= {p}hold * L * L if rg else "
               f"abs(want) * tqb_plain <= {p}hold * L):",
               "    tq = 0.0",
               "else:",
               "    tq = torque(want)",
               f"if tq > {p}hold:",
               "    lo = 0.0",
               "    hi = abs(want)",
               "    sign = 1.0 if want > 0 else -1.0",
               "    for _ in range(40):",
               "        mid = 0.5 * (lo + hi)",
               f"        if torque(sign * mid) > {p}hold:",
               "            hi = mid",
               "        else:",
               "            lo = mid",
               "    actual = sign * lo",
               f"    {p}lost = turns_cmd - actual",
               "    want = actual",
               "turns = want"]


def _missed_steps_pullout(s: Snip, e: Any, p: str, E: str) -> None:
    s.params += [(f"{p}t0", f"{E}.params.pullout_torque_Nm"), (f"{p}wc", f"{E}.params.corner_speed_turns_per_s"),
                 (f"{p}n", f"{E}.params.slip_exponent")]
    s.memory += [(f"{p}lost", "lost_turns"), (f"{p}pcmd", "_prev_cmd"), (f"{p}prev", "_prev")]
    s.body += [f"prev_cmd = turns_cmd if {p}pcmd is None else {p}pcmd",
               "speed = abs(turns_cmd - prev_cmd) / dt if moving and dt > 0.0 else 0.0",
               f"{p}pcmd = turns_cmd",
               f"want = turns_cmd - {p}lost",
               f"prev = want if {p}prev is None else {p}prev",
               "if abs(want) > abs(prev) and want * prev >= 0.0:",
               f"    limit = {p}t0 / (1.0 + speed / {p}wc)",
               "    tq = torque(want)",
               "    if tq > limit:",
               f"        actual = prev + (want - prev) * (limit / tq) ** {p}n",
               f"        {p}lost += want - actual",
               "        want = actual",
               f"{p}prev = want",
               "turns = want"]


def _missed_steps_saturating(s: Snip, e: Any, p: str, E: str) -> None:
    s.params += [(f"{p}thr", f"{E}.params.threshold_turns"), (f"{p}slip", f"min(1.0, {E}.params.slip_fraction)")]
    s.memory += [(f"{p}lost", "lost_turns"), (f"{p}prev", "_prev")]
    s.body += [f"want = turns_cmd - {p}lost",
               f"prev = want if {p}prev is None else {p}prev",
               "if abs(want) > abs(prev) and want * prev >= 0.0:",
               f"    beyond = abs(want) - max(abs(prev), {p}thr)",
               "    if beyond > 0.0:",
               f"        loss = {p}slip * beyond * (1.0 if want > 0 else -1.0)",
               f"        {p}lost += loss",
               "        want -= loss",
               f"{p}prev = want",
               "turns = want"]


def _thermal_dynamics(s: Snip, e: Any, p: str, E: str) -> None:
    s.params += [(f"{p}rth", f"{E}.params.thermal_resistance_K_per_W"),
                 (f"{p}heat", f"{E}.params.heat_capacity_J_per_K * {E}.params.thermal_resistance_K_per_W"),
                 (f"{p}cool", f"{E}.params.cooling_time_constant_s")]
    s.memory.append((f"{p}t", "_t"))
    s.cells += [(f"{p}mdt", "None"), (f"{p}mtau", "None"), (f"{p}mf", "0.0")]
    s.body += [f"if {p}t is None:",
               f"    {p}t = amb",
               f"t_ss = amb + (volts * volts / R0 * {p}rth if R0 > 0.0 else 0.0)",
               # at its steady state (t_ss - t is a zero) a non-zero temperature stays as it is
               f"if dt > 0.0 and (t_ss != {p}t or {p}t == 0.0):",
               f"    tau = {p}heat if t_ss > {p}t else {p}cool",
               f"    if dt != {p}mdt or tau != {p}mtau:",
               f"        {p}mf = 1.0 - exp(-dt / tau)",
               f"        {p}mdt = dt",
               f"        {p}mtau = tau",
               f"    {p}t += (t_ss - {p}t) * {p}mf",
               f"T = {p}t"]


def _thermal_contraction(s: Snip, e: Any, p: str, E: str) -> None:
    if not e.params.strain_per_K:
        return  # k * (T - T_amb) is 0 (or NaN): never > 0
    s.params += [(f"{p}k", f"{E}.params.strain_per_K"), (f"{p}max", f"{E}.params.max_strain")]
    s.body += [f"st_ = {p}k * (T - amb)",
               "if st_ > 0.0:",
               f"    L *= 1.0 - (st_ if st_ < {p}max else {p}max)"]


def _twist_stiffening(s: Snip, e: Any, p: str, E: str) -> None:
    if not e.params.per_turn:
        return  # the effect itself does nothing at 0
    s.params.append((f"{p}k", f"{E}.params.per_turn"))
    s.body.append(f"kf *= 1.0 + {p}k * abs(turns)")


def _thermal_softening(s: Snip, e: Any, p: str, E: str) -> None:
    if not e.params.per_K:
        return
    s.params.append((f"{p}s", f"{E}.params.per_K"))
    s.body += ["dT = T - amb",
               "if dT > 0.0:",
               f"    kf /= 1.0 + {p}s * dT"]


def _thermal_actuation(s: Snip, e: Any, p: str, E: str) -> None:
    if not e.params.strain_per_K:
        return
    s.params += [(f"{p}k", f"{E}.params.strain_per_K"), (f"{p}max", f"{E}.params.max_strain"),
                 (f"{p}h", f"{E}.params.hysteresis_K")]
    s.memory.append((f"{p}tp", "_tp"))
    s.body += [f"tp = T if {p}tp is None else min(T + {p}h, max(T - {p}h, {p}tp))",
               f"{p}tp = tp",
               "dT = tp - amb",
               "if dT > 0.0:",
               f"    L *= 1.0 - {p}max * tanh({p}k * dT / {p}max)"]


def _load_dependence(s: Snip, e: Any, p: str, E: str) -> None:
    s.params += [(f"{p}ref", f"{E}.params.reference_load_g"), (f"{p}exp", f"{E}.params.hysteresis_exponent"),
                 (f"{p}soft", f"{E}.params.stiffness_softening")]
    s.perload_vars.append(f"{p}hs")
    s.perload += [f"ratio = load_g / {p}ref",
                  f"{p}hs = ratio ** {p}exp if ratio > 0.0 else 0.0"]
    s.body += [f"hs = {p}hs",
               f"kfac = 1.0 - {p}soft * contraction",
               "kf *= kfac if kfac > 0.2 else 0.2"]


def _twist_hysteresis(s: Snip, e: Any, p: str, E: str) -> None:
    s.params.append((f"{p}play", f"{E}.params.play_turns"))
    s.memory.append((f"{p}w", "_w"))
    s.body += [f"r = {p}play * hs",
               f"w = turns if {p}w is None else {p}w",
               "lo = turns - r",
               "hi = turns + r",
               "w = lo if w < lo else hi if w > hi else w",
               f"{p}w = w",
               "te = w"]


def _string_compliance(s: Snip, e: Any, p: str, E: str) -> None:
    s.params.append((f"{p}K", f"{E}.params.stiffness_N"))
    s.body.append(f"L *= 1.0 + load_N / ({p}K * kf)")


def _radius_growth(s: Snip, e: Any, p: str, E: str) -> None:
    s.body.append("rg = True")


def _length_creep_twist(s: Snip, e: Any, p: str, E: str) -> None:
    s.params += [(f"{p}g", f"{E}.params.creep_fraction"), (f"{p}tau", f"{E}.params.time_constant_s")]
    s.memory.append((f"{p}lag", "_lag"))
    s.body += [f"if {p}lag is None:",
               f"    {p}lag = te",
               "elif dt > 0.0:",
               f"    {p}lag += (te - {p}lag) * (1.0 - exp(-dt / {p}tau))",
               f"te = te - {p}g * (te - {p}lag)"]


def _length_creep(s: Snip, e: Any, p: str, E: str) -> None:
    s.params += [(f"{p}s", f"{E}.params.strain_per_N"), (f"{p}tau", f"{E}.params.time_constant_s")]
    s.memory.append((f"{p}x", "_x"))
    s.cells += [(f"{p}mdt", "None"), (f"{p}mf", "0.0")]
    s.perload_vars.append(f"{p}target")
    s.perload.append(f"{p}target = {p}s * load_N")
    s.body += ["if dt > 0.0:",
               f"    if dt != {p}mdt:",
               f"        {p}mf = 1.0 - exp(-dt / {p}tau)",
               f"        {p}mdt = dt",
               f"    {p}x += ({p}target - {p}x) * {p}mf",
               f"x *= 1.0 + {p}x"]


def _settling(target: str, hold: str) -> Callable[[Snip, Any, str, str], None]:
    def snip(s: Snip, e: Any, p: str, E: str) -> None:
        if not getattr(e.params, hold):
            # no hold draws: the offset is the constant run offset (+ the hold offset, 0)
            s.params.append((f"{p}off", f"{E}.run_offset + {E}.hold_offset"))
            s.body.append(f"{target} += {p}off")
            s.export_lines += ["if t_prev is not None:", f"    {E}._moving = moving_prev",
                               f"    {E}._volts = volts_last"]
            return
        s.params += [(f"{p}sd", f"{E}.params.{hold}"), (f"{p}run", f"{E}.run_offset"),
                     (f"{p}gauss", f"{E}.rng.gauss")]
        s.memory += [(f"{p}hold", "hold_offset"), (f"{p}mv", "_moving"), (f"{p}volts", "_volts")]
        s.body += [f"if ({p}mv and not moving) or ({p}volts is not None and volts != {p}volts):",
                   f"    {p}hold = {p}gauss(0.0, {p}sd)",
                   f"{p}mv = moving",
                   f"{p}volts = volts",
                   f"{target} += {p}run + {p}hold"]
    return snip


def _resistance_length(s: Snip, e: Any, p: str, E: str) -> None:
    s.params += [(f"{p}a", f"{E}.params.ohm_per_mm"), (f"{p}c", f"{E}.params.contact_ohm_per_turn")]
    s.body.append(f"R += ({p}a * (x - L0) - {p}c * abs(te))")


def _resistance_hysteresis(s: Snip, e: Any, p: str, E: str) -> None:
    n = len(e._unit)
    s.params += [(f"{p}g", f"{E}.params.ohm_per_mm"), (f"{p}alpha", f"{E}.params.alpha_mm"),
                 (f"{p}beta", f"{E}.params.beta"), (f"{p}lam", f"{E}.params.rate_weight"),
                 (f"{p}eps", f"{E}.params.epsilon"), (f"{p}unit", f"{E}._unit")]
    s.memory += [(f"{p}rate", "_rate"), (f"{p}was", "_was_moving"), (f"{p}sx", "_stop_x"), (f"{p}st", "_stop_t")]
    unroll = n <= UNROLL_OPERATORS
    ws = [f"{p}w{i}" for i in range(n)]
    rs = [f"{p}r{i}" for i in range(n)]
    # thresholds u_i * scale, recomputed when the rate changes (it changes only at motor stops)
    s.cells.append((f"{p}mrate", "None"))
    if unroll:
        s.cells += [(v, "0.0") for v in rs]
        s.cells.append((f"{p}init", f"{E}._w is not None"))
        s.load_lines += [f"if {p}init:"] + [f"    {w} = {E}._w[{i}]" for i, w in enumerate(ws)] + \
                        ["else:"] + [f"    {w} = 0.0" for w in ws]
        s.cells += [(w, None) for w in ws]   # declared nonlocal; set by the load lines above
        s.export_lines.append(f"{E}._w = [{', '.join(ws)}] if {p}init else None")
    else:
        s.cells += [(f"{p}rs", "[]"), (f"{p}wl", f"{E}._w")]
        s.export_lines.append(f"{E}._w = {p}wl")
    s.body += [f"if {p}was and not moving:",
               f"    if {p}sx is not None and t_s > {p}st:",
               f"        {p}rate = abs(x - {p}sx) / (t_s - {p}st)",
               f"    {p}sx = x",
               f"    {p}st = t_s",
               f"elif {p}sx is None:",
               f"    {p}sx = x",
               f"    {p}st = t_s",
               f"{p}was = moving",
               f"if {p}rate != {p}mrate or {p}mrate is None:",
               f"    scale = {p}alpha * log({p}beta + {p}lam * {p}rate ** {p}eps)",
               f"    {p}mrate = {p}rate"]
    if unroll:
        s.body += [f"    {r} = {p}unit[{i}] * scale" for i, r in enumerate(rs)] + [f"    {p}hx = None"]
        s.body += [f"if not {p}init:", f"    {p}init = True", f"    {p}hx = None"] + [f"    {w} = x" for w in ws]
        # at the same length and thresholds as the last sample every operator is already within
        # its band (it was clamped to it): nothing moves, the sum is the last one
        s.body += [f"if x == {p}hx:", f"    total = {p}htotal", "else:"]
        s.cells += [(f"{p}hx", "None"), (f"{p}htotal", "0.0")]
        loop = ["total = 0.0"]
        for w, r in zip(ws, rs):
            loop += [f"lo = x - {r}",
                       f"if {w} < lo:",
                       f"    {w} = lo",
                       "else:",
                       f"    hi = x + {r}",
                       f"    if {w} > hi:",
                       f"        {w} = hi",
                       f"total += {w} - x"]
        s.body += ["    " + line for line in loop] + [f"    {p}hx = x", f"    {p}htotal = total"]
    else:
        s.body += [f"    {p}rs = [u * scale for u in {p}unit]",
                   f"if {p}wl is None:",
                   f"    {p}wl = [x] * {n}",
                   f"wl = {p}wl",
                   "total = 0.0",
                   f"for i, r in enumerate({p}rs):",
                   "    wi = wl[i]",
                   "    if wi < x - r:",
                   "        wi = x - r",
                   "    elif wi > x + r:",
                   "        wi = x + r",
                   "    wl[i] = wi",
                   "    total += wi - x"]
    s.body.append(f"R += {p}g * hs * total / {n}")


def _resistance_transient_decay(s: Snip, e: Any, p: str, E: str) -> None:
    s.params += [(f"{p}b1", f"{E}.params.b1_ohm"), (f"{p}b2", f"{E}.params.b2_ohm"),
                 (f"{p}eps", f"{E}.params.epsilon_s"), (f"{p}settle", f"{E}.params.settle_s"),
                 (f"{p}fs", f"{E}._f_settle")]
    s.body += [f"if not moving and since < {p}settle:",
               f"    lg = log(since + {p}eps)",
               f"    R += {p}b1 * lg * lg + {p}b2 * lg - {p}fs"]


def _resistance_creep(s: Snip, e: Any, p: str, E: str) -> None:
    s.params.append((f"{p}k", f"{E}.params.ohm_per_turn"))
    s.body.append(f"R += {p}k * travel")


def _resistance_temperature(s: Snip, e: Any, p: str, E: str) -> None:
    s.params.append((f"{p}a", f"{E}.params.alpha_per_K"))
    s.body.append(f"R *= 1.0 + {p}a * (T - amb)")


def _resistance_transient_stretched(s: Snip, e: Any, p: str, E: str) -> None:
    s.params += [(f"{p}a", f"{E}.params.amp_ohm"), (f"{p}tau", f"{E}.params.time_constant_s"),
                 (f"{p}beta", f"{E}.params.beta")]
    s.body += ["if not moving and since < inf:",
               f"    R += {p}a * exp(-((since / {p}tau) ** {p}beta))"]


def _resistance_transient_two_exp(s: Snip, e: Any, p: str, E: str) -> None:
    s.params += [(f"{p}a1", f"{E}.params.a1_ohm"), (f"{p}t1", f"{E}.params.tau1_s"),
                 (f"{p}a2", f"{E}.params.a2_ohm"), (f"{p}t2", f"{E}.params.tau2_s")]
    s.body += ["if not moving and since < inf:",
               f"    R += {p}a1 * exp(-since / {p}t1) + {p}a2 * exp(-since / {p}t2)"]


def _resistance_creep_time(s: Snip, e: Any, p: str, E: str) -> None:
    s.params += [(f"{p}k", f"{E}.params.ohm_per_hour / 3600.0 * {E}.params.time_constant_s"),
                 (f"{p}tau", f"{E}.params.time_constant_s")]
    s.memory.append((f"{p}t0", "_t0"))
    s.body += [f"if {p}t0 is None:",
               f"    {p}t0 = t_s",
               f"R += {p}k * (1.0 - exp(-(t_s - {p}t0) / {p}tau))"]


def _sensor_noise(s: Snip, e: Any, p: str, E: str) -> None:
    ln, rn = e.params.length_noise_mm, e.params.resistance_noise_ohm
    if not (ln or rn):
        return
    s.params += [(f"{p}ln", f"{E}.params.length_noise_mm"), (f"{p}rn", f"{E}.params.resistance_noise_ohm")]
    if INLINE_GAUSS:
        s.params.append((f"{p}rnd", f"{E}.rng.random"))
        s.cells.append((f"{p}gnext", f"{E}.rng.gauss_next"))
        s.export_lines.append(f"{E}.rng.gauss_next = {p}gnext")
    else:
        s.params.append((f"{p}gauss", f"{E}._gauss"))
    if ln:
        s.body += _gauss_lines("z", f"{p}ln", "x", p)
    if rn:
        s.body += _gauss_lines("z", f"{p}rn", "R", p)


def _quantisation(s: Snip, e: Any, p: str, E: str) -> None:
    if e.params.length_resolution_mm:
        s.params.append((f"{p}ql", f"{E}.params.length_resolution_mm"))
        s.body.append(f"x = round(x / {p}ql) * {p}ql")
    if e.params.resistance_resolution_ohm:
        s.params.append((f"{p}qr", f"{E}.params.resistance_resolution_ohm"))
        s.body.append(f"R = round(R / {p}qr) * {p}qr")


def _drift(target: str, param: str, gain: bool) -> Callable[[Snip, Any, str, str], None]:
    def snip(s: Snip, e: Any, p: str, E: str) -> None:
        if not getattr(e.params, param):      # a rate of 0 does nothing (the chain's apply returns at once)
            return
        s.params.append((f"{p}k", f"{E}.params.{param}"))
        s.memory.append((f"{p}t0", "_t0"))
        s.body += [f"if {p}t0 is None:",
                   f"    {p}t0 = t_s",
                   f"{target} *= 1.0 + {p}k * ((t_s - {p}t0) / 3600.0)" if gain else
                   f"{target} += {p}k * ((t_s - {p}t0) / 3600.0)"]
    return snip


SNIPPETS: dict[str, Callable[[Snip, Any, str, str], None]] = {
    "missed_steps": _missed_steps, "missed_steps_pullout": _missed_steps_pullout,
    "missed_steps_saturating": _missed_steps_saturating,
    "thermal_dynamics": _thermal_dynamics, "thermal_contraction": _thermal_contraction,
    "twist_stiffening": _twist_stiffening, "thermal_softening": _thermal_softening,
    "thermal_actuation": _thermal_actuation, "load_dependence": _load_dependence,
    "twist_hysteresis": _twist_hysteresis, "string_compliance": _string_compliance, "radius_growth": _radius_growth,
    "length_creep_twist": _length_creep_twist, "length_creep": _length_creep,
    "length_settling": _settling("x", "hold_sd_mm"), "resistance_settling": _settling("R", "hold_sd_ohm"),
    "resistance_length": _resistance_length, "resistance_hysteresis": _resistance_hysteresis,
    "resistance_transient_decay": _resistance_transient_decay, "resistance_creep": _resistance_creep,
    "resistance_temperature": _resistance_temperature,
    "resistance_transient_stretched": _resistance_transient_stretched,
    "resistance_transient_two_exp": _resistance_transient_two_exp, "resistance_creep_time": _resistance_creep_time,
    "sensor_noise": _sensor_noise, "quantisation": _quantisation,
    "length_offset_drift": _drift("x", "mm_per_hour", False), "length_gain_drift": _drift("x", "per_hour", True),
    "resistance_offset_drift": _drift("R", "ohm_per_hour", False),
    "resistance_gain_drift": _drift("R", "per_hour", True),
}
