"""Studies of many simulated runs (``tsa-bench sweep``), executed on Dask distributed.

- :mod:`.study`: the study file (validated, file:line errors) and its points;
  :mod:`.schema`: what a point's configuration may hold; :mod:`.plant`,
  :mod:`.effects`, :mod:`.protocols`: what a point simulates;
- :mod:`.points`: the point runners (simulate, diagnose, fit, reproduce);
- :mod:`.engine`: running the points on a Dask cluster (local by default);
- :mod:`.table`: the tidy, resumable results table (Parquet, one row per point);
- :mod:`.stats` and :mod:`.report`: intervals and the standard figures.

docs/sweep.md is the user's guide.
"""

from tsa_bench.sweep.study import Axis, Point, Study, load_study

__all__ = ["Axis", "Point", "Study", "load_study"]
