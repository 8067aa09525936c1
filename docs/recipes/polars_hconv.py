"""Polars plans the query (a scan, filters, selections), hconv converts its result batch by
batch, and pyarrow writes one Parquet file with hconv's settings.

    python docs/recipes/polars_hconv.py 'data/*.parquet' omega-polars.parquet
"""

import sys

import polars as pl
import pyarrow.parquet as pq

import hconv

src, dst = sys.argv[1], sys.argv[2]
# Polars drops the files' field metadata, where their units are: units_of reads them from the
# files' footers, so that hconv reads each column in its own unit, not in SI.
units = hconv.units_of(src)
job = hconv.Job(method="exact", field_units=units)  # conventions, units and column names, as for hconv convert

frames = pl.scan_parquet(src)  # any LazyFrame: what runs in Polars runs before hconv
schema_in = pl.DataFrame(schema=frames.collect_schema()).to_arrow().schema
schema = hconv.output_schema(schema_in, job=job)
with pq.ParquetWriter(dst, schema, **hconv.parquet_write_options(schema)) as writer:
    # in the files' order: maintain_order=True is collect_batches' default
    for frame in frames.collect_batches(chunk_size=65536):
        writer.write_table(hconv.convert_table(frame.to_arrow(), job=job))
print(f"wrote {dst}: {pq.read_metadata(dst).num_rows} rows")
