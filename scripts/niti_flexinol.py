"""Import the public NiTi (Flexinol) data set and ask what the thesis's models make of it.

Usage: PYTHONPATH=host python3 scripts/niti_flexinol.py [--data DIR] [--held-out 150] [--keep DIR]

DIR defaults to ../shared/data/niti_flexinol/ beside the repository (the data set is
read there, never copied into the project; its README gives source and licence). Each
file (temperature degC, strain, stress MPa; no time column) is imported with
`tsa-bench import` semantics: temperature, strain and stress become extra columns
with their units, t = row index x 1 s. Then Preisach (M = 20) and third-order
polynomial models of temperature -> strain are fitted per stress, one stress held out,
and the held-out stress is predicted from the others (nearest stress, interpolated
between the neighbouring stresses, one model pooled over the others). The figures
printed are the ones quoted in docs/niti-flexinol.md.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from tsa_bench.models.transfer import transfer_study
from tsa_bench.importers.csv_import import import_csv
from tsa_bench.store.reader import read_run

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT.parent / "shared" / "data" / "niti_flexinol"
STRESSES_MPA = (50.0, 100.0, 150.0, 172.0, 200.0)


def import_all(data: Path, out: Path) -> dict[float, object]:
    runs = {}
    for s in STRESSES_MPA:
        path = import_csv(data / f"filtered_data_{s:g}MPa.txt", out / f"niti_{s:g}MPa.h5",
                          {"temperature": "Temperature", "strain": "Strain", "stress": "Stress"},
                          {"temperature": "degC", "strain": "1", "stress": "MPa"},
                          {"source": "maestrolab/calibrating data/NiTi_flexinol (MIT)", "stress_MPa": f"{s:g}"},
                          sample_period_s=1.0)
        runs[s] = read_run(path)
    return runs


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT, help=f"data directory (default {DEFAULT})")
    ap.add_argument("--held-out", type=float, default=150.0, help="stress (MPa) to hold out (default 150)")
    ap.add_argument("--keep", type=Path, default=None, help="keep the imported run files here")
    args = ap.parse_args()
    if not (args.data / "filtered_data_50MPa.txt").exists():
        print(f"error: {args.data}: NiTi data set not found (expected filtered_data_*MPa.txt)", file=sys.stderr)
        return 2
    out = args.keep or Path(tempfile.mkdtemp(prefix="niti-"))
    out.mkdir(parents=True, exist_ok=True)
    runs = import_all(args.data, out)
    for s, r in runs.items():
        st = r.samples["stress"]
        print(f"{s:5g} MPa: {len(r)} samples, columns {', '.join(k for k in r.samples if k in ('temperature', 'strain', 'stress'))}"
              f" ({r.units['temperature']}, {r.units['strain']}, {r.units['stress']}); stress {st.mean():.1f} +- {st.std():.1f} MPa")
    print(f"\ntemperature -> strain, M = 20 Preisach vs cubic, {args.held_out:g} MPa held out (E_aver, strain):")
    for model in ("preisach", "polynomial"):
        res = transfer_study(runs, model, "temperature", "strain", args.held_out)
        ident = ", ".join(f"{c:g} MPa {e:.5f}" for c, e in res.identification.items())
        print(f"{model:10s} identification: {ident}")
        print(f"{'':10s} held out {args.held_out:g} MPa: nearest stress {res.nearest:.5f}, interpolated "
              f"{res.interpolated:.5f}, pooled {res.pooled:.5f}")
    print(f"(run files in {out})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
