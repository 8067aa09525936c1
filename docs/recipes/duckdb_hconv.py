"""DuckDB reads (a glob of Parquet files, or any query), hconv converts batch by batch, and
pyarrow writes one Parquet file with hconv's settings.

    python docs/recipes/duckdb_hconv.py 'data/*.parquet' omega-duckdb.parquet
"""

import sys

import duckdb
import pyarrow.parquet as pq

import hconv

src, dst = sys.argv[1], sys.argv[2]
# DuckDB drops the files' field metadata, where their units are: units_of reads them from the
# files' footers, so that hconv reads each column in its own unit, not in SI.
units = hconv.units_of(src)
job = hconv.Job(method="exact", field_units=units)  # conventions, units and column names, as for hconv convert

con = duckdb.connect()
# A plain scan keeps the files' order (glob order, then row order): DuckDB's
# preserve_insertion_order is on by default. Add ORDER BY when the query joins or aggregates.
reader = con.sql("SELECT * FROM read_parquet(?)", params=[src]).to_arrow_reader(65536)
schema = hconv.output_schema(reader.schema, job=job)
with pq.ParquetWriter(dst, schema, **hconv.parquet_write_options(schema)) as writer:
    for batch in reader:
        writer.write_table(hconv.convert_table(batch, job=job))
print(f"wrote {dst}: {pq.read_metadata(dst).num_rows} rows")
