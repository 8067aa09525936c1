"""Regenerate the shipped example scene: python examples/make_scene.py (from the repository root)."""
from pathlib import Path

import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from hconv.scene import make_scene

here = Path(__file__).parent / "data"
table = pa.table(make_scene(400, seed=2026))
with open(here / "scene.csv", "wb") as f:
    f.write((",".join(table.column_names) + "\n").encode())
    pacsv.write_csv(table, f, pacsv.WriteOptions(include_header=False, quoting_style="none"))
pq.write_table(table, here / "scene.parquet")
print(f"wrote {table.num_rows} rows to {here / 'scene.csv'} and {here / 'scene.parquet'}")
