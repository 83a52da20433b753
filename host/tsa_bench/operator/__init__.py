"""The operator channel: how questions and prompts reach a person, and answers come back.

:mod:`.channel` holds the interface every part that needs a person uses (the runner's
load prompts and twist-zero question, the rig commands' confirmations and typed
readings) and the automatic operator of simulated benches; :mod:`.terminal` is the
person at this terminal. A lab supervisor, a web page or a Bluesky plan implements the
same interface. This room imports nothing else of tsa_bench.
"""

from tsa_bench.operator.channel import AutoOperator, OperatorAbsent, OperatorChannel, Pausable

__all__ = ["AutoOperator", "OperatorAbsent", "OperatorChannel", "Pausable"]
