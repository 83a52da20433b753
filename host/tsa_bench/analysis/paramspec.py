"""One free parameter of the judged model: its search range, scale and weak prior.

Units: ``lo``, ``hi`` and the values in the parameter's own units (``tsa-bench effects``);
``prior`` in log units for a log parameter.

Contract: a :class:`ParamSpec` maps one plant-config entry (``"geometry.<key>"`` or
``"<effect>.<param>"``) to an optimiser variable ``u`` in [0, 1], linearly or
logarithmically between ``lo`` and ``hi`` (see :mod:`tsa_bench.analysis.modelspec` for
the bounds, the priors and the model's own parameters; :mod:`tsa_bench.analysis.families`
for the parameters of each candidate form).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class ParamSpec:
    key: str          # "geometry.radius_mm" or "effect.param"
    lo: float
    hi: float
    log: bool = False
    hard_lo: bool = False
    hard_hi: bool = False
    prior: float = 0.0   # prior std (log units when log); 0: none

    def to_value(self, u: float) -> float:
        u = min(1.0, max(0.0, float(u)))
        if self.log:
            return math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo)))
        return self.lo + u * (self.hi - self.lo)

    def to_u(self, value: float) -> float:
        if self.log:
            v = min(self.hi, max(self.lo, value))
            return (math.log(v) - math.log(self.lo)) / (math.log(self.hi) - math.log(self.lo))
        return min(1.0, max(0.0, (value - self.lo) / (self.hi - self.lo)))

    def prior_sd(self, centre: float) -> float:
        """Prior standard deviation (log units for log parameters); for linear ones ``prior``
        is a floor and the prior is as wide as the centre itself (a factor-of-two belief)."""
        return self.prior if self.log else max(self.prior, abs(centre))

    def prior_residual(self, value: float, centre: float) -> float:
        if self.prior <= 0:
            return 0.0
        if self.log:
            return (math.log(max(value, 1e-300)) - math.log(max(centre, 1e-300))) / self.prior
        return (value - centre) / self.prior_sd(centre)

    def with_range(self, v: float) -> "ParamSpec":
        """The spec widened (softly) to contain ``v``."""
        lo = min(self.lo, v) if not self.log or v > 0 else self.lo
        hi = max(self.hi, v)
        return ParamSpec(self.key, lo, hi, self.log, self.hard_lo, self.hard_hi, self.prior)
