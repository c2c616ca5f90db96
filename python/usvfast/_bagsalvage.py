"""Open damaged ROS bags: recover every complete record without the index or the summary.

`open_bag` opens a bag with rosbags' AnyReader. When the container itself is damaged (the
common field case: a recording interrupted by power loss or a full disk) it recovers what the
file still holds and opens that instead, as `rosbag reindex` does for ROS 1:

- ROS 1 `.bag` cut short (no index, or an index cut off): the chunks are read in file order
  without the index; every complete chunk's messages are kept, an uncompressed chunk cut by
  the end of the file keeps its complete messages.
- ROS 2 sqlite3 (`.db3`) with damaged pages ("database disk image is malformed"): every row
  sqlite can still read is kept (row by row, so one bad page costs only its rows).
- ROS 2 folder without `metadata.yaml`: the topics and messages are read from the `.db3`
  (or `.mcap`) storage file itself.
- MCAP without its summary and footer: the records are read in file order (chunks
  decompressed one by one, the cut one dropped).

The recovered messages are written to a new, valid bag in a temporary folder (removed on
close) and opened with AnyReader; a DamagedRecordsWarning says what was recovered and what
was lost. `BagSalvage.lost` counts what could not be recovered (chunks, rows, records).
"""

from __future__ import annotations

import re
import shutil
import sqlite3
import struct
import tempfile
import warnings
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from usvfast._damage import DamagedRecordsWarning

#: An MCAP file starts (and, when complete, ends) with this magic.
MCAP_MAGIC = b"\x89MCAP0\r\n"
#: Rows probed past the last readable one before a damaged sqlite table is given up.
_SQLITE_PROBE = 4096


@dataclass
class _Conn:
    topic: str
    msgtype: str
    msgdef: str = ""
    md5sum: str = ""
    callerid: str | None = None
    latching: int | None = None


@dataclass
class BagSalvage:
    """What a recovery kept: `messages` recovered, `lost` damaged units (chunks, rows or
    records) that could not be read, `reason` why the bag needed recovery."""

    reason: str
    messages: int = 0
    lost: int = 0
    conns: dict[int, _Conn] = field(default_factory=dict)
    records: list[tuple[int, int, bytes]] = field(default_factory=list)  # (conn, ns, raw)


# ----------------------------------------------------------------------------- ROS 1
def _ros1_header(buf: bytes, pos: int) -> tuple[dict[str, bytes], int] | None:
    """Parse a ROS 1 record header at `pos`: (fields, position after it) or None if cut."""
    if pos + 4 > len(buf):
        return None
    (size,) = struct.unpack_from("<I", buf, pos)
    end = pos + 4 + size
    if end > len(buf):
        return None
    fields: dict[str, bytes] = {}
    p = pos + 4
    while p < end:
        if p + 4 > end:
            raise ValueError("header field size")
        (n,) = struct.unpack_from("<I", buf, p)
        if p + 4 + n > end:
            raise ValueError("header field too long")
        name, sep, value = buf[p + 4 : p + 4 + n].partition(b"=")
        if not sep:
            raise ValueError("header field without '='")
        fields[name.decode("latin-1")] = value
        p += 4 + n
    return fields, end


def _ros1_records(buf: bytes, pos: int = 0) -> Iterator[tuple[dict[str, bytes], bytes, bool]]:
    """Yield (header, data, complete) of the ROS 1 records from `pos`. The last one is
    incomplete (`complete` False, `data` what is left of it) when `buf` ends inside it; a
    header cut or unparsable ends the stream with an empty incomplete record."""
    while pos < len(buf):
        try:
            parsed = _ros1_header(buf, pos)
        except ValueError:
            parsed = None
        if parsed is None or parsed[1] + 4 > len(buf):
            yield {}, b"", False
            return
        header, p = parsed
        (size,) = struct.unpack_from("<I", buf, p)
        data = buf[p + 4 : p + 4 + size]
        yield header, data, len(data) == size
        pos = p + 4 + size


def _ros1_connection(header: dict[str, bytes], data: bytes) -> tuple[int, _Conn]:
    from rosbags.typesys.msg import normalize_msgtype

    conn_id = struct.unpack("<I", header["conn"])[0]
    inner = _ros1_header(struct.pack("<I", len(data)) + data, 0)
    if inner is None:
        raise ValueError("connection record cut")
    f = inner[0]
    latching = f.get("latching", b"").decode()
    return conn_id, _Conn(
        topic=header["topic"].decode(),
        msgtype=normalize_msgtype(f["type"].decode()),
        msgdef=f.get("message_definition", b"").decode(),
        md5sum=f.get("md5sum", b"").decode(),
        callerid=f["callerid"].decode() if "callerid" in f else None,
        latching=int(latching) if latching else None,
    )


def _salvage_ros1(path: Path, reason: str) -> BagSalvage:
    from rosbags.rosbag1.reader import decompressors

    buf = path.read_bytes()
    magic = b"#ROSBAG V2.0\n"
    if not buf.startswith(magic):
        raise ValueError(f"bag: {path} is not a ROS 1 bag (version 2.0)")
    out = BagSalvage(reason)

    def take(header: dict[str, bytes], data: bytes) -> None:
        op = header.get("op", b"\x00")[:1]
        if op == b"\x07":
            conn_id, conn = _ros1_connection(header, data)
            out.conns.setdefault(conn_id, conn)
        elif op == b"\x02" and "conn" in header and "time" in header:
            conn_id = struct.unpack("<I", header["conn"])[0]
            sec, nsec = struct.unpack("<II", header["time"])
            out.records.append((conn_id, sec * 1_000_000_000 + nsec, data))

    for header, data, complete in _ros1_records(buf, len(magic)):
        op = header.get("op", b"\x00")[:1]
        if op != b"\x05":  # connections of the index section; the rest is index data
            if complete:
                take(header, data)
            else:
                out.lost += int(op == b"\x00" or op == b"\x02")
            continue
        compression = header.get("compression", b"none").decode()
        if not complete:
            out.lost += 1  # the chunk cut by the end of the file
            if compression != "none":
                continue
        else:
            try:
                data = decompressors[compression](data) if compression != "none" else data
            except Exception:  # bz2 / lz4 raise their own types on damaged streams
                out.lost += 1
                continue
        for inner, inner_data, inner_complete in _ros1_records(data):
            if inner_complete:
                take(inner, inner_data)
    out.messages = len(out.records)
    return out


# ----------------------------------------------------------------------------- ROS 2 sqlite3
def _salvage_sqlite(db: Path, reason: str, expected: int | None) -> BagSalvage:
    """Every row of `db`'s messages table sqlite can still read, row by row."""
    out = BagSalvage(reason)
    con = sqlite3.connect(f"file:{db}?mode=ro&immutable=1", uri=True)
    # a truncated file: use the pages present instead of refusing the whole database
    con.execute("PRAGMA writable_schema=ON")
    try:
        try:
            defs = {
                r[0]: r[1]
                for r in con.execute(
                    "SELECT topic_type, encoded_message_definition FROM message_definitions"
                )
            }
        except sqlite3.DatabaseError:
            defs = {}
        try:
            for tid, name, msgtype in con.execute("SELECT id, name, type FROM topics"):
                out.conns[tid] = _Conn(name, msgtype, defs.get(msgtype, ""))
        except sqlite3.DatabaseError as exc:
            raise ValueError(f"bag: {db}: the topics table is unreadable ({exc})") from exc
        try:
            rows = list(con.execute("SELECT topic_id, timestamp, data FROM messages"))
            out.records = [(t, ts, bytes(d)) for t, ts, d in rows]
        except sqlite3.DatabaseError:
            # damaged pages: read row by row, so a bad page costs only its rows
            out.records = []
            rowid, misses, errors, tail_errors = 1, 0, 0, 0
            while misses < _SQLITE_PROBE or (expected is not None and rowid <= expected):
                try:
                    row = con.execute(
                        "SELECT topic_id, timestamp, data FROM messages WHERE id = ?", (rowid,)
                    ).fetchone()
                except sqlite3.DatabaseError:
                    row = None
                    tail_errors += 1
                if row is None:
                    misses += 1
                else:
                    out.records.append((row[0], row[1], bytes(row[2])))
                    errors, tail_errors, misses = errors + tail_errors, 0, 0
                rowid += 1
            # rows after the last readable one: their number is unknown without metadata
            lost = errors + int(tail_errors > 0)
            out.lost = max(expected - len(out.records), 0) if expected is not None else lost
    finally:
        con.close()
    out.messages = len(out.records)
    return out


# ----------------------------------------------------------------------------- MCAP
def _mcap_str(buf: bytes, p: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, p)
    return buf[p + 4 : p + 4 + n].decode(), p + 4 + n


def _mcap_decompress(compression: str, data: bytes, size: int) -> bytes:
    if compression == "":
        return data
    if compression == "lz4":
        from lz4.frame import decompress

        return decompress(data)
    if compression == "zstd":
        try:
            from compression import zstd  # type: ignore[import-not-found]
        except ImportError:
            from backports import zstd  # type: ignore[import-not-found,no-redef]
        return zstd.decompress(data)
    raise ValueError(f"compression {compression!r}")


def _salvage_mcap(path: Path, reason: str) -> BagSalvage:
    """The schemas, channels and messages of an MCAP file read in order, without its summary;
    a chunk or record cut by the end of the file (or that fails to decompress) is lost."""
    buf = path.read_bytes()
    if not buf.startswith(MCAP_MAGIC):
        raise ValueError(f"bag: {path} is not an MCAP file")
    out = BagSalvage(reason)
    schemas: dict[int, tuple[str, str]] = {}

    def walk(data: bytes, pos: int, top: bool) -> None:
        while pos + 9 <= len(data):
            op = data[pos]
            (length,) = struct.unpack_from("<Q", data, pos + 1)
            body = pos + 9
            if body + length > len(data):
                out.lost += 1  # cut by the end of the file
                if op == 0x06 and top:  # an uncompressed chunk keeps its complete messages
                    with suppress(struct.error, UnicodeDecodeError):
                        compression, p = _mcap_str(data, body + 28)
                        if compression == "":
                            walk(data[p + 8 :], 0, False)
                return
            rec = data[body : body + length]
            pos = body + length
            try:
                if op == 0x03:  # schema: id, name, encoding, data
                    (sid,) = struct.unpack_from("<H", rec, 0)
                    name, p = _mcap_str(rec, 2)
                    _, p = _mcap_str(rec, p)
                    (n,) = struct.unpack_from("<I", rec, p)
                    schemas[sid] = (name, rec[p + 4 : p + 4 + n].decode())
                elif op == 0x04:  # channel: id, schema id, topic, encoding, metadata
                    cid, sid = struct.unpack_from("<HH", rec, 0)
                    topic, _ = _mcap_str(rec, 4)
                    name, msgdef = schemas.get(sid, ("", ""))
                    out.conns.setdefault(cid, _Conn(topic, name, msgdef))
                elif op == 0x05:  # message: channel, sequence, log time, publish time, data
                    cid, _, log_time, _ = struct.unpack_from("<HIQQ", rec, 0)
                    out.records.append((cid, log_time, rec[22:]))
                elif op == 0x06 and top:  # chunk
                    _, _, size, _ = struct.unpack_from("<QQQI", rec, 0)
                    compression, p = _mcap_str(rec, 28)
                    (n,) = struct.unpack_from("<Q", rec, p)
                    walk(_mcap_decompress(compression, rec[p + 8 : p + 8 + n], size), 0, False)
                elif op == 0x02:  # footer: the end
                    return
            except (struct.error, UnicodeDecodeError, ValueError, RuntimeError, OSError):
                out.lost += 1  # a damaged record (zstd / lz4 raise these on bad streams)

    walk(buf, len(MCAP_MAGIC), True)
    out.records = [r for r in out.records if r[0] in out.conns]
    out.messages = len(out.records)
    return out


# ----------------------------------------------------------------------------- open
def _write(salvage: BagSalvage, dest: Path, ros1: bool, typestore: Any) -> Path:
    """Write the recovered messages to a new bag at `dest` (ROS 1 file or ROS 2 folder)."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import Writer as Writer2

    records = sorted(salvage.records, key=lambda r: r[1])
    if ros1:
        with Writer1(dest) as w:
            conns = {
                cid: w.add_connection(
                    c.topic,
                    c.msgtype,
                    msgdef=c.msgdef or None,
                    md5sum=c.md5sum or None,
                    callerid=c.callerid,
                    latching=c.latching,
                    typestore=None if c.msgdef else typestore,
                )
                for cid, c in salvage.conns.items()
            }
            for cid, ts, raw in records:
                if cid in conns:
                    w.write(conns[cid], ts, raw)
        return dest
    with Writer2(dest, version=8) as w:
        conns = {}
        for cid, c in salvage.conns.items():
            if c.msgdef and c.msgtype not in typestore.fielddefs:
                conns[cid] = w.add_connection(
                    c.topic, c.msgtype, msgdef=c.msgdef, rihs01="RIHS01_" + "0" * 64
                )
            else:
                conns[cid] = w.add_connection(c.topic, c.msgtype, typestore=typestore)
        for cid, ts, raw in records:
            if cid in conns:
                w.write(conns[cid], ts, raw)
    return dest


def _ros2_storage(folder: Path) -> tuple[Path | None, int | None]:
    """The storage file of a ROS 2 bag folder and the message count its metadata states."""
    expected = None
    meta = folder / "metadata.yaml"
    if meta.is_file():
        m = re.search(r"^\s{4}message_count:\s*(\d+)", meta.read_text(errors="replace"), re.M)
        expected = int(m.group(1)) if m else None
    files = sorted(folder.glob("*.db3")) + sorted(folder.glob("*.mcap"))
    return (files[0] if files else None), expected


def salvage_bag(path: Path, reason: str, typestore: Any) -> BagSalvage:
    """Recover what the damaged bag at `path` holds (see the module docstring).

    Raises ValueError naming what is missing when nothing can be recovered.
    """
    if path.is_dir():
        storage, expected = _ros2_storage(path)
        if storage is None:
            raise ValueError(f"bag: {path} has no metadata.yaml and no .db3 or .mcap storage file")
    else:
        storage, expected = path, None
    if storage.suffix == ".bag":
        return _salvage_ros1(storage, reason)
    if storage.suffix == ".mcap":
        return _salvage_mcap(storage, reason)
    return _salvage_sqlite(storage, reason, expected)


def _needs_salvage(path: Path) -> str | None:
    """Why a bag must be recovered before AnyReader reads it: a ROS 2 folder without
    metadata.yaml, or sqlite pages that cannot be read (found by counting the rows)."""
    if not path.is_dir():
        return None
    if not (path / "metadata.yaml").is_file():
        return "no metadata.yaml"
    storage, expected = _ros2_storage(path)
    if storage is None or storage.suffix != ".db3":
        return None
    con = sqlite3.connect(f"file:{storage}?mode=ro&immutable=1", uri=True)
    try:
        (count,) = con.execute("SELECT count(*), sum(length(data)) FROM messages").fetchone()[:1]
    except sqlite3.DatabaseError as exc:
        return str(exc)
    finally:
        con.close()
    if expected is not None and count < expected:
        return f"{count} of the {expected} messages in metadata.yaml are in the database"
    return None


@contextmanager
def open_bag(path: Path, typestore: Any) -> Iterator[Any]:
    """AnyReader over the bag at `path` (ROS 1 file or ROS 2 folder), recovering a damaged
    one first (module docstring). The reader gets an attribute `salvage` (a BagSalvage, or
    None when the bag was intact). Raises AnyReaderError / ValueError when nothing can be
    read, FileNotFoundError when `path` does not exist."""
    from rosbags.highlevel import AnyReader, AnyReaderError

    reason = None
    try:
        reason = _needs_salvage(path)
        if reason is None:
            reader = AnyReader([path], default_typestore=typestore)
            reader.open()
    except (AnyReaderError, sqlite3.DatabaseError) as exc:
        reason = str(exc)
    except Exception as exc:  # storage libraries' own errors (apsw, lz4, zstd) on bad bytes
        reason = f"{type(exc).__name__}: {exc}"
    if reason is None:
        try:
            reader.salvage = None  # pyright: ignore[reportAttributeAccessIssue]
            yield reader
        finally:
            reader.close()
        return
    try:
        salvage = salvage_bag(path, reason, typestore)
    except (ValueError, OSError, KeyError, struct.error) as exc:
        raise ValueError(f"bag: cannot read {path}: {reason}; recovery failed: {exc}") from exc
    if not salvage.messages:
        raise ValueError(f"bag: cannot read {path}: {reason}; no message could be recovered")
    warnings.warn(
        f"{path}: damaged bag ({reason}); recovered {salvage.messages} message(s), "
        f"lost {salvage.lost} damaged chunk(s)/row(s)/record(s)",
        DamagedRecordsWarning,
        stacklevel=3,
    )
    tmp = Path(tempfile.mkdtemp(prefix="usvfast-salvage-"))
    try:
        ros1 = path.suffix == ".bag" and not path.is_dir()
        fixed = _write(salvage, tmp / ("recovered.bag" if ros1 else "recovered"), ros1, typestore)
        salvage.records = []
        reader = AnyReader([fixed], default_typestore=typestore)
        reader.open()
        try:
            reader.salvage = salvage  # pyright: ignore[reportAttributeAccessIssue]
            yield reader
        finally:
            reader.close()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
