"""A lone MCAP file's messages of one topic read through the file's own index, each record read once.

rosbags reads a whole chunk (often one camera image and its CameraInfo) to give any message in it,
and copies the message's bytes three times on the way. An indexed MCAP file (its summary holds the
channels and the chunk indexes; each chunk is followed by a message index per channel) says where
each message of a channel lies: with uncompressed chunks, the message is read straight from the
file, and a topic of small messages (a CameraInfo) is read without reading the images beside it.
Files without a summary or with compressed chunks are left to rosbags (:func:`topic_messages`
gives None). The messages come in rosbags' order: by log time, then by chunk, then as written.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from typing import BinaryIO

_MAGIC = b"\x89MCAP0\r\n"
_FOOTER = 1 + 8 + 8 + 8 + 4  # opcode, length, summary start, summary offset start, summary CRC
_CHUNK_HEAD = 1 + 8 + 8 + 8 + 8 + 4  # opcode, length, start and end times, uncompressed size, CRC
_MESSAGE_HEAD = 1 + 8 + 2 + 4 + 8 + 8  # opcode, length, channel, sequence, log time, publish time


class McapIndexError(ValueError):
    """The file's index points at something that is not the message it says."""


def _string(buf: bytes, at: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, at)
    return buf[at + 4 : at + 4 + n].decode(), at + 4 + n


def _summary(f: BinaryIO, size: int) -> tuple[dict[int, str], list[tuple]] | None:
    """The channels' topics by id and the chunk indexes ``(start, compression, {channel: index offset})``."""
    if size < 2 * len(_MAGIC) + _FOOTER:
        return None
    f.seek(size - len(_MAGIC) - _FOOTER)
    tail = f.read(len(_MAGIC) + _FOOTER)
    if tail[-len(_MAGIC) :] != _MAGIC or tail[0] != 0x02:
        return None
    (start,) = struct.unpack_from("<Q", tail, 9)
    if not 0 < start <= size - len(_MAGIC) - _FOOTER:
        return None
    f.seek(start)
    buf = f.read(size - len(_MAGIC) - _FOOTER - start)
    topics: dict[int, str] = {}
    chunks: list[tuple] = []
    at = 0
    while at + 9 <= len(buf):
        op, length = buf[at], struct.unpack_from("<Q", buf, at + 1)[0]
        body = at + 9
        if op == 0x04:  # channel: id, schema id, topic, ...
            topics[struct.unpack_from("<H", buf, body)[0]] = _string(buf, body + 4)[0]
        elif op == 0x08:  # chunk index: times, chunk start and length, message index offsets, ...
            (chunk_start,) = struct.unpack_from("<Q", buf, body + 16)
            (n,) = struct.unpack_from("<I", buf, body + 32)
            offsets = dict(struct.iter_unpack("<HQ", buf[body + 36 : body + 36 + n]))
            compression, _ = _string(buf, body + 36 + n + 8)
            chunks.append((chunk_start, compression, offsets))
        at = body + length
    return topics, chunks


def topic_messages(f: BinaryIO, topic: str, count: int | None = None) -> Iterator[tuple[int, bytes]] | None:
    """``(log time ns, CDR bytes)`` of each message on ``topic``, read as the index says; None when unindexed.

    Parameters
    ----------
    f : binary file
        The MCAP file, open for reading (seekable).
    topic : str
        The topic (one channel; a topic on several channels is left to rosbags).
    count : int, optional
        The number of messages the topic holds (the bag's statistics): an index that lists another
        number (message indexes are optional in MCAP, messages may lie outside chunks) is not used.

    Returns
    -------
    iterator of (int, bytes) or None
        None: no summary, no chunk index, compressed chunks, several channels on the topic, or not
        ``count`` messages in the index. The iterator raises
        ``McapIndexError`` or ``struct.error`` when a record is not what the index says.
    """
    f.seek(0, 2)
    size = f.tell()
    found = _summary(f, size)
    if found is None:
        return None
    topics, chunks = found
    ids = [cid for cid, t in topics.items() if t == topic]
    if len(ids) != 1 or not chunks or any(compression for _, compression, _ in chunks):
        return None
    cid = ids[0]
    where: list[tuple[int, int, int]] = []
    for chunk_start, _, offsets in chunks:
        if cid not in offsets:
            continue
        f.seek(offsets[cid])
        head = f.read(15)
        if len(head) < 15 or head[0] != 0x07 or struct.unpack_from("<H", head, 9)[0] != cid:
            raise McapIndexError("a message index is not where the chunk index says")
        (n,) = struct.unpack_from("<I", head, 11)
        records = chunk_start + _CHUNK_HEAD + 4 + 8  # an empty compression name, then the records' length
        where += [(t, chunk_start, records + off) for t, off in struct.iter_unpack("<QQ", f.read(n))]
    if count is not None and len(where) != count:
        return None
    return _read(f, sorted(where), cid, size)


def _read(f: BinaryIO, where: list[tuple[int, int, int]], cid: int, size: int) -> Iterator[tuple[int, bytes]]:
    for log_time, _, at in where:
        f.seek(at)
        head = f.read(_MESSAGE_HEAD)
        if len(head) < _MESSAGE_HEAD or head[0] != 0x05:
            raise McapIndexError("a message is not where the message index says")
        (length,) = struct.unpack_from("<Q", head, 1)
        channel, _, t = struct.unpack_from("<HIQ", head, 9)
        if channel != cid or t != log_time or not 22 <= length <= size - at - 9:
            raise McapIndexError("a message is not the one the message index says")
        data = f.read(length - 22)
        if len(data) != length - 22:
            raise McapIndexError("a message is cut short")
        yield log_time, data
