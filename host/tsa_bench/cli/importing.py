"""`tsa-bench import`: a measured data file from another lab -> a run file (docs/importing.md).

Exit codes: 0 written; 2 bad input (unreadable or unsupported file, bad options, a cell,
unit or clock problem), with a message naming the file, the line and the column, and
nothing written.
"""

from __future__ import annotations

import sys

import click

from tsa_bench.cli.catalogue import CATALOGUE_OPTION
from tsa_bench.cli.loading import MAX_MEMORY
from tsa_bench.cli.exits import EXIT_BAD_INPUT


def _pairs(values: tuple[str, ...], option: str) -> dict[str, str]:
    """'a=b,c=d' (option may repeat) -> {a: b, c: d}; exits 2 on a malformed pair."""
    out: dict[str, str] = {}
    for value in values:
        for part in value.split(","):
            if not part.strip():
                continue
            key, sep, val = part.partition("=")
            if not sep or not key.strip() or not val.strip():
                click.echo(f"error: {option}: '{part}' is not KEY=VALUE", err=True)
                sys.exit(EXIT_BAD_INPUT)
            out[key.strip()] = val.strip()
    return out


def _numbers(pairs: dict[str, str], option: str) -> dict[str, float]:
    out = {}
    for k, v in pairs.items():
        try:
            out[k] = float(v)
        except ValueError:
            click.echo(f"error: {option}: {k}={v!r} is not a number", err=True)
            sys.exit(EXIT_BAD_INPUT)
    return out


@click.command("import")
@click.argument("source", type=click.Path(dir_okay=False))
@click.option("--map", "maps", multiple=True,
              help="Target = source column (name or 1-based position), comma-separated, e.g. t=time_s,length=3,"
                   "force=F_N. Targets: contract columns, the channels temperature, force, pressure, stress, "
                   "strain, current, voltage, angle, or any other name (an extra column). Columns not mapped "
                   "are still picked up when named like these or when their header gives a unit.")
@click.option("--units", "unit_opts", multiple=True,
              help="Column = unit, e.g. t=ms,load=g,temperature=K, for columns whose header gives none "
                   "(a header unit that disagrees is an error).")
@click.option("--no-header", is_flag=True, help="Text/xlsx: the first row is data; map columns by position.")
@click.option("--delimiter", default=None,
              help="Text: the cell delimiter (default: found from the file; 'tab' and 'space' accepted).")
@click.option("--decimal", type=click.Choice([".", ","]), default=None,
              help="Text: the decimal separator (default: a decimal comma is found when the delimiter is not ',').")
@click.option("--sheet", default=None, help="xlsx: the worksheet (default: the first).")
@click.option("--var", default=None, help="MATLAB .mat: the variable (a matrix or a struct of vectors).")
@click.option("--group", default=None, help="TDMS: the channel group (default: the first with channels).")
@click.option("--sample-period", "sample_period_s", type=float, default=None,
              help="The file has no time column: t = row index x this period (s), rows in file order.")
@click.option("--time-order", type=click.Choice(["error", "sort", "drop"]), default="error", show_default=True,
              help="Rows whose time is not after the rows before: refuse, sort by time (repeats dropped), "
                   "or drop them.")
@click.option("--segments", "segments", default="infer", show_default=True,
              help="infer (moves, holds, heater and load changes from the data), none, or column=NAME.")
@click.option("--segment-threshold", "thresholds", multiple=True,
              help="Override inference settings, e.g. turns=0.01,heater_V=0.1,load_N=0.2, their hysteresis "
                   "turns_hyst, heater_hyst_V, load_hyst_N (default a fifth of the threshold) and the minimum "
                   "duration min_s (s).")
@click.option("--load-g", "load_g", type=float, default=None,
              help="The hanging load (g) of the whole run, stored as the declared load (same as --const load=Gg).")
@click.option("--const", "consts", multiple=True,
              help="A column of one value for every row: NAME=VALUE[UNIT], e.g. load=200g, temperature=23degC.")
@click.option("--scale", "scales", multiple=True,
              help="COLUMN=FACTOR multiplies a column (in its stored unit), or COLUMN=FACTOR UNIT calibrates a "
                   "transducer's output, e.g. length=2.5mm/V for a column in V (repeatable, comma-separated).")
@click.option("--offset", "offsets", multiple=True,
              help="COLUMN=X[UNIT] adds X (stored unit unless given), after --negate and --scale, e.g. length=250.")
@click.option("--negate", "negates", multiple=True,
              help="COLUMN: change the sign of a column (a stage position counted the other way, a meter's sign).")
@click.option("--meta", "metas", multiple=True, help="KEY=VALUE stored in the run's metadata (repeatable).")
@click.option("--out", "out_file", type=click.Path(dir_okay=False), required=True, help="Run file to write.")
@CATALOGUE_OPTION
@MAX_MEMORY
def import_cmd(source: str, maps: tuple[str, ...], unit_opts: tuple[str, ...], no_header: bool,
               delimiter: str | None, decimal: str | None, sheet: str | None, var: str | None, group: str | None,
               sample_period_s: float | None, time_order: str, segments: str, thresholds: tuple[str, ...],
               load_g: float | None, consts: tuple[str, ...], scales: tuple[str, ...], offsets: tuple[str, ...],
               negates: tuple[str, ...], metas: tuple[str, ...], out_file: str, catalogue_url: str | None) -> None:
    """Turn SOURCE (CSV/TSV/text, .xlsx, MATLAB .mat, LabVIEW .tdms) into a run file (backend "import").

    Prints every source column and where it went, what was done to the clock, the sample
    rate and the segments found. Columns beyond the contract (temperature, force,
    pressure, ...) are kept as extra /samples columns with their units."""
    from tsa_bench.importers import ImportFileError, ImportOptions, import_file

    meta: dict[str, str] = {}
    for m in metas:  # one pair per --meta: the value may contain commas
        key, sep, value = m.partition("=")
        if not sep or not key.strip():
            click.echo(f"error: --meta: '{m}' is not KEY=VALUE", err=True)
            sys.exit(EXIT_BAD_INPUT)
        meta[key.strip()] = value
    constants = _pairs(consts, "--const")
    if load_g is not None:
        if "load" in constants:
            click.echo("error: --load-g and --const load=... both declare the load; give one", err=True)
            sys.exit(EXIT_BAD_INPUT)
        constants["load"] = f"{load_g:g}g"
    options = ImportOptions(mapping=_pairs(maps, "--map") if maps else None, units=_pairs(unit_opts, "--units"),
                            meta=meta, sample_period_s=sample_period_s, no_header=no_header, delimiter=delimiter,
                            decimal=decimal, sheet=sheet, var=var, group=group, time_order=time_order,
                            segments=segments, thresholds=_numbers(_pairs(thresholds, "--segment-threshold"),
                                                                   "--segment-threshold"),
                            constants=constants, scale=_pairs(scales, "--scale"), offset=_pairs(offsets, "--offset"),
                            negate=[c.strip() for n in negates for c in n.split(",") if c.strip()])
    try:
        summary = import_file(source, out_file, options)
    except ImportFileError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(EXIT_BAD_INPUT)
    except OSError as exc:
        click.echo(f"error: cannot write {out_file}: {exc}", err=True)
        sys.exit(EXIT_BAD_INPUT)
    for line in summary.lines:
        click.echo(line)
    for warning in summary.warnings:
        click.echo(f"warning: {warning}", err=True)
    click.echo(f"wrote {summary.path} ({summary.n_samples} samples)")
    from tsa_bench.cli.catalogue import register_file

    register_file(catalogue_url, summary.path)
