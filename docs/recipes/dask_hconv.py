"""Dask DataFrame: each partition goes to hconv as Arrow data and comes back with Arrow dtypes;
Dask writes one Parquet file per partition, with hconv's schema and settings, in names that sort.

    python docs/recipes/dask_hconv.py data/ omega-dask/
"""

import sys

import dask.dataframe as dd
import pandas as pd
import pyarrow as pa
import pyarrow.dataset as ds

import hconv

src, dst = sys.argv[1], sys.argv[2]
# pandas drops the files' field metadata, where their units are: units_of reads them from the
# files' footers, so that hconv reads each column in its own unit, not in SI.
units = hconv.units_of(src)
job = hconv.Job(method="exact", field_units=units)  # conventions, units and column names, as for hconv convert


def omega(part: pd.DataFrame) -> pd.DataFrame:
    table = hconv.convert_table(pa.Table.from_pandas(part, preserve_index=False), job=job)
    return table.to_pandas(types_mapper=pd.ArrowDtype)


frames = dd.read_parquet(src, dtype_backend="pyarrow")  # one partition per file, in name order
schema_in = pa.Schema.from_pandas(frames._meta, preserve_index=False)
schema = hconv.output_schema(schema_in, job=job)
result = frames.map_partitions(omega, meta=schema.empty_table().to_pandas(types_mapper=pd.ArrowDtype))
result.to_parquet(
    dst,
    schema=schema,  # without it Dask infers one from pandas, and wx, wy, wz lose their unit
    name_function=lambda k: f"part-{k:05d}.parquet",  # Dask's part.10 sorts before part.2
    write_index=False,
    **hconv.parquet_write_options(schema),
)
# counted in the files' footers: len(result) would read and convert everything again
print(f"wrote {dst}: {ds.dataset(dst).count_rows()} rows")
