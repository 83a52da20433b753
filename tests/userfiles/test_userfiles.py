"""The hardened reader every user file goes through (tsa_bench.userfiles)."""

from __future__ import annotations

import os
import sys
import time

import pytest

from tsa_bench.userfiles import DocumentError, YamlLimits, parse_json, parse_yaml, read_json, read_text_file, read_yaml

BOMB = ("a: &a [x,x,x,x,x,x,x,x,x]\n" + "".join(
    f"{c}: &{c} [{', '.join([f'*{p}'] * 9)}]\n" for p, c in zip("abcdefgh", "bcdefghi")))


def error_of(text: str, **limits) -> DocumentError:
    with pytest.raises(DocumentError) as info:
        parse_yaml(text, "f.yaml", YamlLimits(**limits)).data()
    return info.value


def test_an_alias_bomb_is_refused_at_once():
    t0 = time.process_time()
    err = error_of(BOMB)
    assert "aliases expand" in str(err) and str(err).startswith("f.yaml:")
    assert time.process_time() - t0 < 5  # generous: it used to take 55 s and 2 GB


@pytest.mark.parametrize("text, where, message", [
    ("a: " + "[" * 100 + "]" * 100, "f.yaml:1:", "nested more than 64"),
    ("a: &x [*x]", "f.yaml:1:4", "cycle"),
    ('a: 1\nb: "x\\ud800y"', "f.yaml:2:4", "lone surrogate"),
    ("a: " + "7" * 4400, "f.yaml:1:4", "4400 digits"),
    ("a: 1\na: 2", "f.yaml:2:1", "duplicate key 'a'"),
    ("a: 2001-02-03", "f.yaml:1:4", "quote it"),
    ("a: !!python/object/apply:os.system [ls]", "f.yaml:1:4", "unsupported"),
    ("a: [1, .inf]", "f.yaml:1:8", "finite"),
    ("? [1]\n: 2", "f.yaml:1:3", "keys must be text"),
    ("a: 1\n---\nb: 2", "f.yaml:2:1", "single document"),
    ("a: b: c", "f.yaml:1:5", "YAML syntax error"),
    ("a: 1\nb: \x07", "f.yaml:2:4", "U+0007"),
])
def test_bad_yaml_names_file_line_and_column(text, where, message):
    err = error_of(text)
    assert str(err).startswith(where) and message in str(err), str(err)
    assert "\n" not in str(err)


def test_plain_data_with_merge_keys_and_exponent_numbers():
    doc = parse_yaml("base: &b {x: 1, y: 2}\nc: {<<: *b, y: 3}\nk: 1e-3\nq: '1e-3'\n", "f.yaml")
    assert doc.data() == {"base": {"x": 1, "y": 2}, "c": {"x": 1, "y": 3}, "k": 1e-3, "q": "1e-3"}
    assert doc.where("c", "y") == "f.yaml:2:16" and doc.where("c", "nope") == "f.yaml:2:4"
    assert parse_yaml("", "e.yaml").data() is None and parse_yaml("# only\n", "e.yaml").root is None


def test_files_must_be_regular_bounded_utf8(tmp_path):
    with pytest.raises(DocumentError, match="bench file not found"):
        read_yaml(tmp_path / "none.yaml", what="bench file")
    with pytest.raises(DocumentError, match="is a directory"):
        read_yaml(tmp_path, what="bench file")
    big = tmp_path / "big.yaml"
    big.write_text("a: 1\n" * 1000)
    with pytest.raises(DocumentError, match="at most 100 are read"):
        read_text_file(big, "protocol", max_bytes=100)
    bad = tmp_path / "latin1.yaml"
    bad.write_bytes("a: 1\nb: caf\xe9\n".encode("latin-1"))
    with pytest.raises(DocumentError) as info:
        read_yaml(bad)
    assert str(info.value).startswith(f"{bad}:2:7: not UTF-8")
    if sys.platform != "win32":
        fifo = tmp_path / "fifo.yaml"
        os.mkfifo(fifo)  # nobody writes it: a reader that opened it would wait for ever
        with pytest.raises(DocumentError, match="FIFO"):
            read_yaml(fifo)


def test_json_limits(tmp_path):
    assert parse_json('{"a": [1, NaN]}')["a"][0] == 1
    for text, message in (("[" * 70 + "]" * 70, "nested"), ("[" * 100000 + "]" * 100000, "nested"),
                          ('{"a": ' + "1" * 50 + "}", "digits"), ('["\\ud800"]', "surrogate"),
                          ('{"a": }', "not valid JSON")):
        with pytest.raises(DocumentError, match=message):
            parse_json(text, "m.json")
    p = tmp_path / "m.json"
    p.write_text('{\n  "a": 1,\n  "b": ]\n}')
    with pytest.raises(DocumentError) as info:
        read_json(p)
    assert str(info.value).startswith(f"{p}:3:8:")
