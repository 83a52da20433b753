"""A second independent data generator for the diagnose tests (numpy only).

It shares no code and no formulation with the library (tsa_bench.sim) or the first
independent generator (tests/analysis/foreign): the TSA is solved through its helix angle
by bisection, the protocols are pyramids and amplitude sweeps (not staircases or random
walks), the rigs and sampling rates are others, and every effect is written in a form
neither the library nor its alternative forms have (power-law transients, logarithmic
creep by Boltzmann superposition, a Dahl-type twist friction, wear growing with the
square root of travel), plus sensor artefacts that a physical effect can mimic and effects
outside the library altogether (a mains beat on the resistance, a twice-per-turn contact
ripple, a periodic non-linearity of the length sensor's track).
"""
