"""Generated protocol files must match the catalogue (CI fails when they are stale)."""

from __future__ import annotations

import subprocess
import sys


def test_generated_files_up_to_date(repo_root):
    result = subprocess.run([sys.executable, str(repo_root / "scripts" / "gen_protocol.py"), "--check"],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_check_detects_a_stale_file(repo_root, tmp_path, monkeypatch):
    sys.path.insert(0, str(repo_root / "scripts"))
    try:
        import gen_protocol
    finally:
        sys.path.pop(0)
    stale = tmp_path / "catalogue.py"
    stale.write_text("# old\n")
    monkeypatch.setattr(gen_protocol, "PY_OUT", stale)
    monkeypatch.setattr(gen_protocol, "MD_OUT", tmp_path / "messages.md")
    monkeypatch.setattr(gen_protocol, "C_OUT", tmp_path / "protocol_catalogue.h")
    monkeypatch.setattr(gen_protocol, "VECTORS_OUT", tmp_path / "golden_vectors.inc")
    assert gen_protocol.main(["--check"]) == 1
    assert gen_protocol.main([]) == 0
    assert gen_protocol.main(["--check"]) == 0
    assert "CATALOGUE_HASH" in stale.read_text()
