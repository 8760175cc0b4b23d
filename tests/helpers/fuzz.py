"""What the fuzzers share: values of any TOML type, and TOML written back from parsed content."""

from __future__ import annotations

import math

from hypothesis import strategies as st


# -- TOML written back ---------------------------------------------------------------------------
def toml_string(text: str) -> str:
    out = []
    for ch in text:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def toml_value(value) -> str:
    if isinstance(value, Nested):
        return value.toml()
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return "{ " + ", ".join(f"{toml_string(k)} = {toml_value(v)}" for k, v in value.items()) + " }"


def toml_dumps(data: dict) -> str:
    lines = [f"{toml_string(k)} = {toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for key, table in data.items():
        if isinstance(table, dict):
            lines.append(f"[{toml_string(key)}]")
            lines += [f"{toml_string(k)} = {toml_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


# -- strategies ----------------------------------------------------------------------------------
SCALARS = st.one_of(
    st.integers(-(2**63), 2**63 - 1),
    st.sampled_from([0, 1, -1, 2**62, 10**9]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, 1e300, 5e-324, 1e-12]),
    st.booleans(),
    st.text(max_size=12),
    st.sampled_from(["rk4", "dopri5", "aim", "flight", "x\x1b[2J", ""]),
)
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=12,
)


class Nested:
    """Arrays or inline tables ``depth`` deep, written out without recursion."""

    def __init__(self, depth: int, arrays: bool) -> None:
        self.depth, self.arrays = depth, arrays

    def toml(self) -> str:
        return (
            "[" * self.depth + "1" + "]" * self.depth
            if self.arrays
            else "{ a = " * self.depth + "1" + " }" * self.depth
        )
