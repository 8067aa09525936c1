"""Ray tasks, one per file: each reads its file batch by batch, converts with hconv and writes an
output file of the same name with hconv's schema and settings, so every row keeps its place.

    python docs/recipes/ray_tasks_hconv.py data/ omega-ray-tasks/
"""

import os
import sys

import pyarrow.parquet as pq
import ray

import hconv

src, dst = sys.argv[1], sys.argv[2]
job = hconv.Job(method="exact")  # conventions, units and column names, as for hconv convert


@ray.remote
def convert(path: str, out: str, job: hconv.Job) -> int:
    with pq.ParquetFile(path) as data:
        schema = hconv.output_schema(data.schema_arrow, job=job, source=path)
        with pq.ParquetWriter(out, schema, **hconv.parquet_write_options(schema)) as writer:
            for batch in data.iter_batches(65536):
                writer.write_table(hconv.convert_table(batch, job=job, source=path))
    return pq.read_metadata(out).num_rows


ray.init(include_dashboard=False)
os.makedirs(dst, exist_ok=True)
names = sorted(name for name in os.listdir(src) if name.endswith(".parquet"))
rows = ray.get([convert.remote(os.path.join(src, name), os.path.join(dst, name), job) for name in names])
print(f"wrote {dst}: {sum(rows)} rows in {len(names)} files")
