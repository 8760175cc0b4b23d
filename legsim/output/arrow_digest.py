"""A SHA-256 of arrow data that does not depend on how it is chunked or which arrow types carry
it: the digest of what a recording logged (``legsim.output.rrd.digest``) and of a sweep's table
(``legsim.sweep.table``).

The values are fed to streams (stream name -> hash), one per nesting level and kind: which
entries are null, the lengths of lists, and at the bottom the numbers (floats as float64,
integers as int64, booleans as bytes) or the UTF-8 text. Rows fed in several pieces give the
streams one piece of all of them gives; a column's digest is the SHA-256 of its streams'.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

import numpy as np


def _feed(streams: dict[str, Any], name: str, data: bytes) -> None:
    if name not in streams:
        streams[name] = hashlib.sha256()
    streams[name].update(data)


def feed_values(streams: dict[str, Any], array: Any, name: str = "values") -> None:
    """Add an arrow array's values to ``streams`` (stream name -> hash): which are null and the
    lengths of lists per nesting level, then numbers or text, whatever arrow types carry them."""
    import pyarrow as pa
    import pyarrow.compute as pc

    kind = array.type
    # Fed for every piece, nulls or none, so that the stream is the same however rows are grouped.
    _feed(streams, f"{name}/nulls", np.asarray(array.is_null().to_numpy(zero_copy_only=False), np.uint8).tobytes())
    if pa.types.is_dictionary(kind):
        array, kind = array.dictionary_decode(), array.type.value_type
    if pa.types.is_list(kind) or pa.types.is_large_list(kind):
        lengths = np.asarray(pc.fill_null(pc.list_value_length(array), 0).to_numpy(zero_copy_only=False), np.int64)
        _feed(streams, f"{name}/lengths", lengths.tobytes())
        feed_values(streams, array.flatten(), f"{name}/items")
    elif pa.types.is_fixed_size_list(kind):
        feed_values(streams, array.flatten(), f"{name}/items")
    elif pa.types.is_struct(kind):
        for field, child in zip(kind, array.flatten(), strict=True):  # flatten: the slice's own rows
            feed_values(streams, child, f"{name}.{field.name}")
    elif pa.types.is_floating(kind):
        values = np.asarray(array.to_numpy(zero_copy_only=False), dtype=np.float64)
        _feed(streams, name, values.tobytes())
    elif pa.types.is_integer(kind) or pa.types.is_boolean(kind):
        filled = pc.fill_null(array, False if pa.types.is_boolean(kind) else 0)
        values = np.asarray(filled.to_numpy(zero_copy_only=False), dtype=np.int64)
        _feed(streams, name, values.tobytes())
    elif pa.types.is_string(kind) or pa.types.is_large_string(kind) or pa.types.is_binary(kind):
        texts = [b"" if v is None else (v.encode("utf-8") if isinstance(v, str) else v) for v in array.to_pylist()]
        _feed(streams, f"{name}/lengths", np.array([len(t) for t in texts], dtype=np.int64).tobytes())
        _feed(streams, name, b"".join(texts))
    elif not pa.types.is_null(kind):
        _feed(streams, name, json.dumps(array.to_pylist(), default=str).encode("utf-8"))


def component_digest(streams: dict[str, Any]) -> str:
    """The SHA-256 (hex) of the streams of one column (an entity's component in a recording)."""
    joined = "".join(f"{name}={h.hexdigest()};" for name, h in sorted(streams.items()))
    return hashlib.sha256(joined.encode("utf-8")).hexdigest()


def table_digest(table: Any) -> str:
    """The SHA-256 (hex) of an arrow table's columns (names and content; not its metadata)."""
    digests = []
    for name in table.column_names:
        streams: dict[str, Any] = {}
        for chunk in table.column(name).chunks:
            feed_values(streams, chunk)
        digests.append(f"{name}={component_digest(streams)};")
    return hashlib.sha256("".join(digests).encode("utf-8")).hexdigest()
