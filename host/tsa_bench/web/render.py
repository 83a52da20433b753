"""One finished run's report figures, drawn in a process of its own for the page's cache.

``python -m tsa_bench.web.render RUN.h5 OUT_DIR DPI`` writes the figures of
:func:`tsa_bench.report.run_report.write_run_report` (PNG at DPI) and ``manifest.json``
into ``OUT_DIR.partial`` and renames it to ``OUT_DIR`` when whole, so a reader sees a
whole report or none. The manifest: ``status``, ``reason``, ``samples``, ``figures``
(``name``, ``file``, ``caption``, ``thesis``), ``skipped`` ({kind: why}) and ``events``
(the last :data:`MAX_EVENTS`: ``t`` in s, ``kind``, ``detail``). Exit 0 when written; 1 with
one line on stderr (the run file's problem) when not.

The caller (:mod:`.figures`) starts it with ``HDF5_USE_FILE_LOCKING=FALSE``: the run file is
read without HDF5's file lock, so the page never makes a writer of that file (a
``--resume`` linking its continuation, a rebuild) fail on a lock. It reads closed runs only.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

MAX_EVENTS = 200


def _events(run) -> list[dict]:
    ev = run.events
    if ev is None or not len(ev):
        return []
    out = []
    for row in ev[-MAX_EVENTS:]:
        t = float(row["t"])
        kind, detail = (row[k].decode(errors="replace") if isinstance(row[k], bytes) else str(row[k])
                        for k in ("kind", "detail"))
        out.append({"t": t if t == t else None, "kind": kind, "detail": detail})
    return out


def render(run_path: Path, out_dir: Path, dpi: int) -> None:
    from tsa_bench.report.run_report import write_run_report

    partial = out_dir.with_name(out_dir.name + ".partial")
    shutil.rmtree(partial, ignore_errors=True)
    report = write_run_report(run_path, partial, fmt="png", dpi=dpi)
    run = report.run
    manifest = {"status": run.exit_status, "reason": str(run.attrs.get("reason", "")), "samples": len(run),
                "figures": [{"name": f.name, "file": f.path.name, "caption": f.caption, "thesis": f.thesis}
                            for f in report.figures],
                "skipped": report.skipped, "events": _events(run)}
    (partial / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    os.replace(partial, out_dir)


def main(argv: list[str]) -> int:
    from tsa_bench.store import RunFileError

    run_path, out_dir, dpi = Path(argv[0]), Path(argv[1]), int(argv[2])
    try:
        render(run_path, out_dir, dpi)
    except (RunFileError, OSError, ValueError) as exc:
        print(" ".join(str(exc).split())[:500], file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
