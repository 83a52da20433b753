"""The lab's page in a browser (`tsa-bench serve`): every rig live, the catalogue, report figures.

It reads the live sidecars the recording processes write and the run catalogue, and
nothing else while a run records: the acquisition never waits for the page. Modules:
:mod:`.board` (the runs being recorded, from their sidecars, in bounded memory),
:mod:`.recent` (the catalogue, read only), :mod:`.figures` and :mod:`.render` (report
figures of finished runs, drawn in a child process and cached), :mod:`.app` (the
Starlette application: server-sent events, JSON, the page in ``static/``), :mod:`.server`
(the address check and uvicorn). The [web] extra installs uvicorn and Starlette.
"""
