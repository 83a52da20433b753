"""The documentation site (docs/, Sphinx): it builds with warnings as errors, the tutorial
notebook executes during the build, and the strict build refuses what it is there to refuse.

Every build goes into pytest's temporary folder, never into the repository.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tsa_bench.cli import COMMANDS

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"


def _sphinx(src: Path, out: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    """``sphinx-build -W`` of ``src`` with docs/conf.py (nitpicky: references checked) into ``out``."""
    env = dict(os.environ)
    # the tutorial's kernel imports the package next to these docs
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "host"), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env.pop("MPLBACKEND", None)    # the kernel's inline backend draws the tutorial's figures
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-E", "-q", "-b", "html", "-T",
           "-c", str(DOCS), "-d", str(out / "doctrees"), *extra, str(src), str(out / "html")]
    out.mkdir(parents=True, exist_ok=True)
    return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900, cwd=out)


def _text(html: Path) -> str:
    body = html.read_text(encoding="utf-8")
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", body))


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    done = _sphinx(DOCS, out)
    assert done.returncode == 0, f"strict docs build failed:\n{done.stdout[-4000:]}\n{done.stderr[-8000:]}"
    assert not re.search(r": (WARNING|ERROR):", done.stderr), done.stderr[-8000:]   # Sphinx's own format
    return out / "html"


def test_every_docs_page_is_in_the_site(site):
    pages = {p.relative_to(DOCS).with_suffix("") for p in DOCS.rglob("*") if p.suffix in (".md", ".ipynb")}
    built = {p.relative_to(site).with_suffix("") for p in site.rglob("*.html")}
    assert pages and pages <= built, sorted(pages - built)


def test_tutorial_ran_during_the_build(site):
    text = _text(site / "tutorial.html")
    # what only an executed notebook shows: the runner's, fit's and diagnose's printed results
    assert "train.h5: success" in text and "check.h5: success" in text
    assert "named: resistance_transient_decay" in text
    assert "explained: the calibrated model leaves only sensor noise" in text
    assert len(list((site / "_images").glob("*.png"))) >= 3    # its figures
    assert "Traceback" not in text


def test_cli_reference_lists_every_command(site):
    html = (site / "cli.html").read_text(encoding="utf-8")
    for name in COMMANDS:
        assert f'id="tsa-bench-{name}"' in html, name
    assert 'id="tsa-bench-calibrate-position"' in html       # subcommands too
    assert "--bench" in _text(site / "cli.html")


def test_api_reference_renders_the_public_functions(site):
    objects = {
        "api/runs.html": ["tsa_bench.store.read_run", "tsa_bench.rundata.RunData"],
        "api/running.html": ["tsa_bench.runner.Runner", "tsa_bench.device.BenchClient", "tsa_bench.bench.load_bench",
                             "tsa_bench.operator.channel.OperatorChannel", "tsa_bench.operator.terminal.TerminalOperator"],
        "api/importing.html": ["tsa_bench.importers.import_file", "tsa_bench.importers.ImportOptions",
                               "tsa_bench.importers.ImportFileError"],
        "api/simulating.html": ["tsa_bench.sim.simulate"],
        "api/models.html": ["tsa_bench.models.fitting.fit", "tsa_bench.models.saved.SavedModel"],
        "api/diagnose.html": ["tsa_bench.analysis.diagnose", "tsa_bench.analysis.DiagnoseResult"],
        "api/bluesky.html": ["tsa_bench.bluesky.device.TsaRig", "tsa_bench.bluesky.flyer.ProtocolFlyer",
                             "tsa_bench.bluesky.plans.run_protocol", "tsa_bench.bluesky.bridge.RunFileWriter",
                             "tsa_bench.bluesky.session.PositionUnknown"],
    }
    for page, names in objects.items():
        html = (site / page).read_text(encoding="utf-8")
        for name in names:
            assert f'id="{name}"' in html, (page, name)
    # a docstring's contract is on the page, not just the signature
    assert "NaN means" in _text(site / "api/runs.html")


def test_readme_sections_are_pages_with_working_links(site):
    index = (site / "index.html").read_text(encoding="utf-8")
    assert 'id="set-up"' in index and 'id="usage"' in index and 'id="run-file"' in index
    assert "quasi-static-self-sensing.yaml" in _text(site / "index.html")   # the first set-up command
    rig = (site / "mega.html").read_text(encoding="utf-8")
    assert "dialout" in rig
    # a README link into docs/ is a link of the site; one elsewhere in the repository is its path
    assert 'href="reliability.html"' in index
    assert re.search(r"<code[^>]*><span[^>]*>firmware/README\.md</span></code>", rig), "firmware link"
    assert 'href="firmware/README.md"' not in rig


def test_strict_build_refuses_broken_links_and_references(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    (src / "index.md").write_text(
        "# Index\n\n[gone](missing-page.md), [no heading](other.md#no-such-heading), [out](../no-such-file.md)\n\n"
        "{func}`tsa_bench.store.no_such_function`, {func}`tsa_bench.store.reader._one_line`\n\n"
        "```{toctree}\nother\n```\n", encoding="utf-8")
    (src / "other.md").write_text("# Other\n", encoding="utf-8")
    (src / "orphan.md").write_text("# In no toctree\n", encoding="utf-8")
    done = _sphinx(src, tmp_path / "out")
    log = done.stderr
    assert done.returncode != 0
    assert "missing-page.md" in log
    assert "no-such-heading" in log
    assert "no-such-file.md" in log          # outside the docs, missing: reported, not made code
    assert "tsa_bench.store.no_such_function" in log
    assert "orphan" in log
    # a private helper that exists is shown as code, not reported
    assert "_one_line" not in log


def test_a_failing_tutorial_cell_fails_the_build(tmp_path):
    import nbformat

    src = tmp_path / "src"
    src.mkdir()
    (src / "index.md").write_text("# Index\n\n```{toctree}\nnb\n```\n", encoding="utf-8")
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("raise ValueError('stale tutorial')")])
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nbformat.write(nb, src / "nb.ipynb")
    done = _sphinx(src, tmp_path / "out")
    assert done.returncode != 0
    assert "stale tutorial" in done.stderr + done.stdout
