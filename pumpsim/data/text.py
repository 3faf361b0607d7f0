"""Reading a text file's bytes and decoding them: UTF-8 (BOM or not), UTF-16 with BOM, else
Windows-1252; binary files refused."""
from __future__ import annotations

import re
from pathlib import Path

from ..errors import DataError


def read_bytes(p: Path) -> bytes:
    try:
        return p.read_bytes()
    except OSError as e:
        raise DataError(f"cannot read: {e.strerror}") from None


def decode_file(p: Path) -> str:
    """Text of a data or config file: UTF-8 (BOM or not), UTF-16 with BOM (spreadsheet 'Unicode
    text'), else Windows-1252; binary files are refused."""
    return decode_text(read_bytes(p), DataError)


UTF8_BOM = b"\xef\xbb\xbf"
# a character of two to four bytes in UTF-8: cp1252 text almost never holds one (it would read 'Ã¼')
_UTF8_MULTIBYTE = re.compile(rb"[\xc2-\xdf][\x80-\xbf]|[\xe0-\xef][\x80-\xbf]{2}|[\xf0-\xf4][\x80-\xbf]{3}")


def refuse_binary(raw: bytes, error) -> None:
    if raw.startswith(b"PK\x03\x04"):
        raise error("is a ZIP archive (an Excel .xlsx workbook?), not text; save it as CSV")
    if raw.startswith(b"PAR1"):
        raise error("is an Apache Parquet file; name it .parquet to be read as one")
    if b"\x00" in raw[:4096]:
        raise error("is a binary file, not text (UTF-8 or UTF-16 with BOM)")


def decode_text(raw: bytes, error=DataError) -> str:
    """UTF-16 with BOM, else UTF-8 (a BOM stripped), else Windows-1252 (also with a UTF-8 BOM in
    front, as some exporters write). Bytes that fit neither are refused naming the byte, its offset
    and line, never decoded to look-alike characters."""
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            return raw.decode("utf-16")
        except UnicodeDecodeError:
            raise error("is not readable UTF-16 text") from None
    refuse_binary(raw, error)
    skip = len(UTF8_BOM) if raw.startswith(UTF8_BOM) else 0
    body = raw[skip:]
    try:
        return body.decode("utf-8")
    except UnicodeDecodeError as e:
        utf8_bad = e.start

    def at(i):
        line = body.count(b"\n", 0, i) + 1
        return f"byte 0x{body[i]:02x} at byte offset {i + skip} (line {line})"

    if _UTF8_MULTIBYTE.search(body):
        raise error(f"is UTF-8 text with an invalid {at(utf8_bad)}: the file is damaged or mixes "
                    "encodings; save it again as UTF-8")
    try:
        return body.decode("cp1252")
    except UnicodeDecodeError as e:
        raise error(f"is neither UTF-8 ({at(utf8_bad)} is not UTF-8) nor Windows-1252 ({at(e.start)} "
                    "is undefined there); save it as UTF-8") from None
