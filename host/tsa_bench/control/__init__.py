"""Closed-loop control and estimation from the strings' own resistance (thesis 5.2, future work).

- :mod:`.estimator`: the self-sensing inverse run online, sample by sample (resistance only),
  and the resistance-and-twist length estimate of a load-strain model;
- :mod:`.controller`: the step controller of the ``track_length`` protocol step;
- :mod:`tsa_bench.models.load_strain` (a fitted model, below control): load and strain estimated together
  from resistance and twist (`tsa-bench estimate`);
- :mod:`.evaluation`: steady-state error, rise time, overshoot and load recovery of a tracking run.

The runner side (sending, run-file columns) is :mod:`tsa_bench.runner.tracking`; docs/control.md.
"""
