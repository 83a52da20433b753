"""An independent generator of TSA runs for testing `diagnose` (numpy only).

Nothing here imports ``tsa_bench``: the plant (kinematics, effects in forms the library
does not use, effects the library does not have), the rotation walks and the run-file
writer are written from the physics and the run-file contract (docs/run-format.md), so
a test built on it checks the engine against data its own simulator did not make.
"""
