"""Spark: hconv converts each partition as Arrow batches (mapInArrow), and Spark writes Parquet.

Spark takes no dictionary type, so status goes as text; it keeps no Arrow field metadata, so ω's
unit goes into Spark's own schema, which Spark stores in the files it writes (pyarrow reads them
without it; hconv.units_of(omega/) and hconv read it); and it reads the files in an order of its
own, so the rows are sorted back by file name and row first.

    python docs/recipes/spark_hconv.py data/ omega-spark/
"""

import os
import sys

import pyarrow as pa
from pyspark.sql import SparkSession
from pyspark.sql.pandas.types import from_arrow_type, to_arrow_schema
from pyspark.sql.types import StructField, StructType

import hconv

src, dst = sys.argv[1], sys.argv[2]
# Spark drops the files' field metadata, where their units are: units_of reads them from the
# files' footers, so that hconv reads each column in its own unit, not in SI.
units = hconv.units_of(src)
job = hconv.Job(method="exact", field_units=units)  # conventions, units and column names, as for hconv convert
os.environ.setdefault("PYSPARK_PYTHON", sys.executable)  # the workers' Python: the one with hconv


def plain(field: pa.Field) -> pa.Field:
    """A dictionary field as one of its values' type, which Spark takes."""
    return field.with_type(field.type.value_type) if pa.types.is_dictionary(field.type) else field


def as_spark(field: pa.Field) -> StructField:
    """An Arrow field as Spark's, its metadata (the unit) into Spark's field metadata."""
    meta = {k.decode(): v.decode() for k, v in (field.metadata or {}).items()}
    return StructField(field.name, from_arrow_type(field.type), field.nullable, meta)


spark = SparkSession.builder.appName("hconv").getOrCreate()
frames = spark.read.parquet(src)
schema = pa.schema([plain(f) for f in hconv.output_schema(to_arrow_schema(frames.schema), job=job)])


def omega(batches):
    for batch in batches:
        yield from hconv.convert_table(batch, job=job).cast(schema).to_batches()


order = ["_metadata.file_name", "_metadata.row_index"]  # file names must sort: part-02, not part-2
result = frames.orderBy(*order).mapInArrow(omega, StructType([as_spark(f) for f in schema]))
result.write.parquet(dst)
# counted in the files' footers: result.count() would read and convert everything again
print(f"wrote {dst}: {spark.read.parquet(dst).count()} rows")
spark.stop()
