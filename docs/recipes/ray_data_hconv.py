"""Ray Data: hconv converts each block as Arrow data, and Ray writes Parquet with hconv's schema
and settings. Ray does not promise the rows' order in what it writes (see ray_tasks_hconv.py
for a recipe that keeps it).

    python docs/recipes/ray_data_hconv.py data/ omega-ray-data/
"""

import sys

import pyarrow.dataset as ds
import ray
import ray.data

import hconv

src, dst = sys.argv[1], sys.argv[2]
job = hconv.Job(method="exact")  # conventions, units and column names, as for hconv convert

ray.init(include_dashboard=False)
# The order held into one output file per write task; with several per task
# (max_rows_per_file) the rows came out reordered even so.
ray.data.DataContext.get_current().execution_options.preserve_order = True
frames = ray.data.read_parquet(src)
schema = hconv.output_schema(frames.schema().base_schema, job=job)
result = frames.map_batches(lambda batch: hconv.convert_table(batch, job=job), batch_format="pyarrow", batch_size=None)
result.write_parquet(dst, arrow_parquet_args_fn=lambda: {"schema": schema, **hconv.parquet_write_options(schema)})
# counted in the files' footers: result.count() would read and convert everything again
print(f"wrote {dst}: {ds.dataset(dst).count_rows()} rows")
