"""CSV in and out (hconv.tables.csvio)."""

from __future__ import annotations


def test_csv_writer_csv_to_csv_text_columns_come_out_byte_for_byte(tmp_path):
    """Before: one value needing quotes made every text value of its batch quoted (1 -> "1",
    02134 -> "02134"), though docs/input.md promises them back exactly as they went in."""
    from hconv.tables.pipeline import convert_file

    rows = ['1,02134,plain text,"a,b",,"say ""hi""",007', '2,00501,x y,z,,"line\nbreak",1e3']
    text = "id,zip,label,note,empty,quote,code,Hx,Hy,Hz,I1,I2,I3\n" + "".join(r + ",1,2,3,1,2,4\n" for r in rows)
    (tmp_path / "in.csv").write_text(text)
    convert_file(str(tmp_path / "in.csv"), str(tmp_path / "out.csv"))
    out = (tmp_path / "out.csv").read_text()
    assert out.startswith("id,zip,label,note,empty,quote,code,Hx,")
    body = out.split("\n", 1)[1]
    assert body.startswith(rows[0] + ",1,2,3,1,2,4,")
    assert "\n" + rows[1] + ",1,2,3,1,2,4," in body
