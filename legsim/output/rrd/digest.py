"""A digest of what legsim logs in a recording, stored in it (``/legsim/digest``) and verified
when it is read back (``legsim replay``).

A Rerun file carries no checksum: a flipped byte in a sample's value is read back as another
value (a height of -6.6 m instead of 0.67 m) without complaint. While it records, legsim hashes
every component it logs, per entity and component, as Rerun stores it: the rows in the order
they were logged (which the reader recovers from Rerun's row ids), each row's sample index
(the ``sample`` timeline; -1 for static data) and its values. The values are hashed as streams
that do not depend on how rows are grouped into chunks: for each nesting level of the arrow
data, the lengths of its lists, and at the bottom the numbers (floats as float64, integers as
int64, booleans as bytes) or the UTF-8 text. Each (entity, component) gets the SHA-256 of its
streams' SHA-256s; the document at ``/legsim/digest`` lists them, with the SHA-256 of the list
itself. Rerun's own bookkeeping and what Rerun's URDF loader logs from the robot's files are
not legsim's logging and are not covered by it.

A recording file written by ``write_rrd`` is also sealed (``seal``): once everything is logged
and flushed, the SHA-256 of the file's bytes so far is logged at ``/legsim/file_digest`` as a
short text of hex fields, ``qz<nonce>z<bytes>z<masked sha256>zq`` (the SHA-256 XOR the
SHA-256 of the nonce). Rerun compresses each message with LZ4, which replaces a run of 4 or more
bytes seen earlier in the message by a reference: the text is made without a repeated 4-byte run
where a nonce can make it so (a fresh nonce changes the nonce and the masked SHA-256, not the
bytes field: ``seal_text``), and the writer checks that it lies in the file verbatim, or logs
another. ``check_file`` finds the last seal in
the raw file and hashes the bytes before it, before Rerun decodes anything: Rerun's reader aborts the whole
process on some damaged files (an arrow offset flipped past its buffer panics in a thread of
its own), so a damaged file must be refused before it gets there. This covers everything
written before the seal, the URDF loader's data included; the seal's own message and what Rerun
writes after it (the blueprint, its footer) are not, so the reader hands Rerun the sealed bytes
alone (``columns.read_columns``). A recording streamed to a viewer is not sealed (the viewer writes its
own bytes); its components' digest still holds.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..arrow_digest import _feed, component_digest, feed_values

#: The document's format, and the hash it uses.
DIGEST_FORMAT = "legsim-rrd-digest-1"
#: The seal's text, as ``check_file`` finds it in the raw file: nonce, bytes covered, SHA-256 (hex).
_SEAL = re.compile(rb"qz([0-9a-f]{8})z([0-9a-f]{1,16})z([0-9a-f]{64})zq")
#: Seals tried before a file is left unsealed (each one fails only when LZ4 shortened its text).
SEAL_ATTEMPTS = 4
#: Nonces tried for one seal's text (a text's random fields repeat a 4-byte run with a
#: chance of about 5%).
NONCE_TRIES = 64
#: Bytes read at a time while hashing or searching a file.
_BLOCK = 1 << 16
#: The longest text ``_SEAL`` matches: a search's blocks overlap by one byte less, so a seal
#: across two blocks lies whole in one of them.
_SEAL_LENGTH = len("qz") + 8 + len("z") + 16 + len("z") + 64 + len("zq")


def list_digest(entities: dict[str, dict[str, str]]) -> str:
    """The SHA-256 (hex) of the list of (entity, component) digests."""
    return hashlib.sha256(json.dumps(entities, sort_keys=True).encode("utf-8")).hexdigest()


class Digest:
    """The streams of every (entity, component) logged so far."""

    def __init__(self) -> None:
        self.streams: dict[tuple[str, str], dict[str, Any]] = {}

    def add(self, entity: str, component: str, rows: Any, index: np.ndarray) -> None:
        """Rows of a component (an arrow list array, one list per row) logged at the sample
        indices ``index`` (-1: static)."""
        streams = self.streams.setdefault((entity, component), {})
        _feed(streams, "sample", np.asarray(index, dtype=np.int64).tobytes())
        feed_values(streams, rows)

    def document(self) -> dict[str, Any]:
        """What ``/legsim/digest`` holds."""
        entities: dict[str, dict[str, str]] = {}
        for (entity, component), streams in sorted(self.streams.items()):
            entities.setdefault(entity, {})[component] = component_digest(streams)
        return {"format": DIGEST_FORMAT, "entities": entities, "digest": list_digest(entities)}


def stored_path(path: str) -> str:
    """An entity path as Rerun stores it: a leading slash, no empty parts (an escaped slash,
    ``\\/``, is no separator and survives the split and join unchanged)."""
    return "/" + "/".join(part for part in path.split("/") if part)


class DigestingStream:
    """A Rerun recording stream whose ``log`` and ``send_columns`` also add what they log to a
    ``Digest``; everything else is the stream's own."""

    def __init__(self, rec: Any, digest: Digest, timeline: str) -> None:
        self._rec, self._digest, self._timeline = rec, digest, timeline

    def __getattr__(self, name: str) -> Any:
        return getattr(self._rec, name)

    def log(self, path: str, entity: Any, *, static: bool = False) -> None:
        """``rec.log`` of a static archetype, digested."""
        import pyarrow as pa

        if not static:
            raise ValueError("legsim logs temporal data with send_columns only (its rows' sample indices)")
        for batch in entity.as_component_batches():
            values = batch.as_arrow_array()
            rows = pa.ListArray.from_arrays(pa.array([0, len(values)], type=pa.int32()), values)
            self._digest.add(stored_path(path), batch.component_descriptor().component, rows, np.array([-1]))
        self._rec.log(path, entity, static=True)

    def send_columns(self, path: str, indexes: Iterable[Any], columns: Iterable[Any]) -> None:
        """``rec.send_columns``, digested with the rows' sample indices."""
        indexes, columns = list(indexes), list(columns)
        sample = next(i for i in indexes if i.timeline_name() == self._timeline)
        index = np.asarray(sample.as_arrow_array().to_numpy(zero_copy_only=False), dtype=np.int64)
        for column in columns:
            self._digest.add(stored_path(path), column.component_descriptor().component, column.as_arrow_array(), index)
        self._rec.send_columns(path, indexes=indexes, columns=columns)


def verify(columns: Any, text: str | None) -> str | None:
    """Check the recorded components against the digest document ``text`` (the contents of
    ``/legsim/digest``, None when the recording has none): the first (entity, component) that
    differs, described, or None when all match. ValueError for a document that is no digest."""
    from ..untrusted import check_object, load_json

    if text is None:
        raise ValueError("legsim/digest is an empty document")
    document = check_object(load_json(text), {"format": (str,), "entities": (dict,), "digest": (str,)}, "legsim/digest")
    if document["format"] != DIGEST_FORMAT:
        raise ValueError(f"legsim/digest is of format {document['format']!r:.40}, not {DIGEST_FORMAT}")
    entities = document["entities"]
    for entity, components in entities.items():
        check_object(components, {}, f"legsim/digest.entities.{entity:.80}")
    if list_digest(entities) != document["digest"]:
        return "the digest document does not match its own digest"
    for entity, components in sorted(entities.items()):
        for component, expected in sorted(components.items()):
            logged = columns.logged(entity, component)
            if logged is None:
                return f"{entity}:{component} has rows without Rerun's row ids"
            index, rows = logged
            if not len(index):
                return f"{entity}:{component} is missing"
            streams: dict[str, Any] = {}
            _feed(streams, "sample", np.asarray(index, dtype=np.int64).tobytes())
            feed_values(streams, rows)
            if component_digest(streams) != expected:
                return f"{entity}:{component} differs from what was logged"
    return None


#: How a complete file of the Rerun SDK this package pins (0.41) ends: its footer's magic, then
#: the footer's 4-byte version. The SDK only logs a failure to write the footer (a disk filling
#: as the stream closes), so the writer looks for it before the file takes its name.
FOOTER_MAGIC = b"RRF2FOOT"
FOOTER_TAIL = len(FOOTER_MAGIC) + 4


def ends_with_footer(path: Path) -> bool:
    """Whether the file ``path`` ends as a finished Rerun file does (``FOOTER_MAGIC``)."""
    size = os.path.getsize(path)
    with open(path, "rb") as fh:
        fh.seek(max(0, size - FOOTER_TAIL))
        return fh.read().startswith(FOOTER_MAGIC)


def seal(rec: Any, path: Path, entity: str) -> bool:
    """Flush ``rec`` (saving to ``path``) and log, at ``entity``, the SHA-256 of the file's bytes
    so far (module docstring); whether a seal lies in the file verbatim."""
    import secrets

    import rerun as rr

    for _ in range(SEAL_ATTEMPTS):
        rec.flush()
        size = os.path.getsize(path)
        text = seal_text(size, _file_hash(path, size), lambda: secrets.token_hex(4))
        rec.log(entity, rr.TextDocument(text, media_type="text/plain"), static=True)
        rec.flush()
        if _last_seal(path, os.path.getsize(path), start=size) is not None:
            return True
    return False


def seal_text(size: int, digest: str, new_nonce: Callable[[], str]) -> str:
    """The seal of a file's first ``size`` bytes whose SHA-256 is ``digest`` (64 hex digits)
    (module docstring): with the first of up to ``NONCE_TRIES`` nonces (8 hex digits each, from
    ``new_nonce``) that leaves no 4-byte run repeated in it, else with the last. The bytes field
    is the same for every nonce, and some sizes repeat a run in it (0x18a18a1: "18a1" twice), so
    a search until no run repeats would never end; such a text may lose its run to LZ4, and the
    writer then sees it is not verbatim in the file and logs another, at the file's new size."""
    text = ""
    for _ in range(NONCE_TRIES):
        nonce = new_nonce()
        text = f"qz{nonce}z{size:x}z{_masked(digest, nonce)}zq"
        if len({text[k : k + 4] for k in range(len(text) - 3)}) == len(text) - 3:
            break
    return text


def _masked(digest: str, nonce: str) -> str:
    """``digest`` (64 hex digits) XOR the SHA-256 of ``nonce``: its own inverse."""
    mask = hashlib.sha256(nonce.encode("ascii")).digest()
    return bytes(a ^ b for a, b in zip(bytes.fromhex(digest), mask, strict=True)).hex()


def _file_hash(path: Path, size: int) -> str:
    digest = hashlib.sha256()
    for block in leading_blocks(path, size):
        digest.update(block)
    return digest.hexdigest()


def leading_blocks(path: Path, size: int) -> Iterator[bytes]:
    """The first ``size`` bytes of the file ``path`` (all of it when shorter), in blocks."""
    with open(path, "rb") as fh:
        left = size
        while left > 0:
            block = fh.read(min(_BLOCK, left))
            if not block:
                return
            yield block
            left -= len(block)


def check_file(path: Path) -> int | None:
    """Whether the sealed part of the recording file ``path`` is as it was written: the number
    of bytes the seal covers (from the file's start) when it is, None when the file holds no
    seal (written before legsim sealed recordings, or by another writer); ValueError describing
    the damage otherwise. Reads the file in blocks: its last occurrence of the seal first, from
    the end."""
    size = os.path.getsize(path)
    found = _last_seal(path, size)
    if found is None:
        return None
    position, sealed, expected = found
    if sealed > position:
        raise ValueError(f"its seal covers {sealed} bytes, past where the seal itself lies ({position})")
    if _file_hash(path, sealed) != expected:
        raise ValueError(f"its first {sealed} bytes no longer match the SHA-256 stored with them")
    return sealed


def _last_seal(path: Path, size: int, start: int = 0) -> tuple[int, int, str] | None:
    """(position, bytes covered, SHA-256) of the last seal in the file's bytes ``start`` to
    ``size``, or None. Reads one block at a time from the end, so that a search through a long
    recording that holds no seal near its end needs no more memory than a short one's."""
    end = size
    with open(path, "rb") as fh:
        while end > start:
            begin = max(start, end - _BLOCK)
            fh.seek(begin)
            matches = list(_SEAL.finditer(fh.read(end - begin)))
            if matches:
                last = matches[-1]
                nonce, digest = last.group(1).decode("ascii"), last.group(3).decode("ascii")
                return begin + last.start(), int(last.group(2), 16), _masked(digest, nonce)
            if begin == start:
                break
            end = begin + _SEAL_LENGTH - 1
    return None
