"""The Python examples of the API pages (docs/api/*.md) run as written, in the order a reader
meets them: "Running" records run.h5 on the simulated bench, the other pages read it. The
blocks of one page run one after the other in one namespace, as in a reader's session."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from tsa_bench.store import FORMAT_VERSION

ROOT = Path(__file__).resolve().parents[2]
API = ROOT / "docs" / "api"
#: pages in reading order; the files each one needs are made by the pages before it
ORDER = ["running", "runs", "importing", "models", "diagnose", "simulating"]


def _blocks(page: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", (API / f"{page}.md").read_text(encoding="utf-8"), re.S | re.M)


def test_every_api_page_with_an_example_is_run():
    with_examples = {p.stem for p in API.glob("*.md") if _blocks(p.stem)}
    assert with_examples == set(ORDER)


def test_api_examples_run(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    printed = {}
    for page in ORDER:
        if page == "models":
            shutil.copy("run.h5", "run2.h5")     # the page's validation run
        session = {"__name__": f"docs_{page}"}
        for block in _blocks(page):
            exec(compile(block, f"docs/api/{page}.md", "exec"), session)
        printed[page] = capsys.readouterr().out
    assert printed["running"].startswith("success ")
    assert printed["runs"].startswith("success ") and " mm" in printed["runs"]
    assert f"\n{FORMAT_VERSION} " in printed["runs"]     # the run file's format, as the page says
    assert printed["importing"].startswith("text 3 samples\n")
    assert "-> temperature (extra column" in printed["importing"] and "import degC" in printed["importing"]
    assert "error: logger.h5 already exists" in printed["importing"]
    assert "mm mean error" in printed["models"]
    assert printed["diagnose"].split()[0] in ("explained", "named", "unexplained", "model_mismatch")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["logger.csv", "logger.h5", "preisach.json", "run.h5", "run2.h5"]
