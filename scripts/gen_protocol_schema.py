"""Write configs/schema/protocol.schema.json from host/tsa_bench/plan/schema.py.

Run: PYTHONPATH=host python3 scripts/gen_protocol_schema.py  (a test fails when it is stale)
"""

from pathlib import Path

from tsa_bench.plan.schema import schema_text

OUT = Path(__file__).resolve().parents[1] / "configs" / "schema" / "protocol.schema.json"

if __name__ == "__main__":
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(schema_text(), encoding="utf-8")
    print(f"wrote {OUT}")
