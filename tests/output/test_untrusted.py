"""Text from outside: JSON read with bounded depth and strict numbers, strings printed with
their control characters escaped, and the type checks of read documents."""

import json

import pytest

from legsim.output.untrusted import check_list, check_object, json_depth, load_json, printable


def test_json_depth_counts_brackets_outside_strings_only():
    assert json_depth('{"a": [1, {"b": "[[[[\\"{{"}], "c": []}') == 3
    assert json_depth("[]") == 1 and json_depth("3") == 0 and json_depth('"[[["') == 0
    # Counting stops once past the limit: a 10^6-deep document costs no parsing.
    assert json_depth("[" * 10**6 + "]" * 10**6, limit=64) == 65


def test_load_json_is_strict_and_bounded():
    assert load_json('{"a": [1, 2.5, "NaN"]}') == {"a": [1, 2.5, "NaN"]}
    assert load_json("[" * 64 + "]" * 64) is not None
    for text, reason in [
        ("[" * 65 + "]" * 65, "nested more than 64 levels deep"),
        ('{"t": NaN}', "NaN is not"),
        ("[Infinity]", "Infinity is not"),
        ("[1e400]", "1e400 is beyond the range"),
        ("{", "Expecting"),
        (None, "expected JSON text"),
    ]:
        with pytest.raises(ValueError, match=reason):
            load_json(text)


def test_printable_escapes_what_a_terminal_would_act_on():
    hostile = "a\x1b[2Jb\rc\x07d\x9be\u202ef\tg\nh"
    assert printable(hostile) == "a\\x1b[2Jb\\rc\\x07d\\x9be\\u202ef\tg\nh"
    assert printable(hostile, newlines=False).endswith("f\\tg\\nh")  # one line, no tab stops
    assert printable("plain ünïcode, 日本") == "plain ünïcode, 日本" and printable(3) == "3"


def test_check_object_names_the_key_and_both_types():
    doc = json.loads('{"n": 1, "x": 2.5, "s": "a", "flag": true, "big": 1' + "0" * 30 + "}")
    schema = {"n": (int,), "x": (int, float), "s": (str,)}
    assert check_object(doc, schema, "meta", optional={"flag": (bool,)}) is doc
    with pytest.raises(ValueError, match=r"^meta lacks \['q'\]$"):
        check_object(doc, {"q": (int,)}, "meta")
    with pytest.raises(ValueError, match=r"^meta\.flag is a boolean, expected int$"):
        check_object(doc, {"flag": (int,)}, "meta")  # True is no number
    with pytest.raises(ValueError, match=r"^meta\.big is an integer, expected int"):
        check_object(doc, {"big": (int,)}, "meta")  # beyond int64: no format prints it
    with pytest.raises(ValueError, match=r"^meta is an array, expected an object$"):
        check_object([], schema, "meta")
    with pytest.raises(ValueError, match=r"^modes\[1\] is an integer, expected str$"):
        check_list(["a", 1], (str,), "modes")
