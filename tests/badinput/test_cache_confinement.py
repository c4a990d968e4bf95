"""Paths read from cache files stay inside their cache folder (issue 36).

A request record of the motion cache names the motion it led to; a forged record whose
``"motion"`` climbs out of the cache (``../../victims/victim``, padded to the key's 64
characters) must not make ``wbmp solve`` read or remove anything outside the cache: the record
is damaged (removed, it is inside), the motion is computed again, exit 0, and the victim files
are untouched. The same holds for every key read from a file of any cache.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.badinput.conftest import Tree, run_cli

REPO = Path(__file__).resolve().parents[2]
SPEC = REPO / "examples" / "specs" / "squat.json"


@pytest.fixture(autouse=True)
def _memory_solvers(monkeypatch):
    monkeypatch.setenv("WBMP_COMPILE", "0")


def escaping_key(prefix: str, length: int = 64) -> str:
    """A relative path of exactly ``length`` characters that starts with ``prefix`` (``../``s):
    ``./`` segments pad it, the file name takes the rest."""
    body = prefix
    while length - len(body) > 8:
        body += "./"
    return body + "v" * (length - len(body))


@pytest.fixture
def cached(tmp_path, monkeypatch, capsys):
    """(cache folder, victims folder) after one solve of the example spec into a fresh cache."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("WBMP_CACHE_DIR", str(cache))
    outcome = run_cli(["solve", "--spec", SPEC, "--no-sim", "--quiet"], capsys)
    assert outcome.code == 0, outcome.err
    victims = tmp_path / "victims"
    victims.mkdir()
    return cache, victims


def _records(cache: Path) -> list[Path]:
    return sorted((cache / "motions" / "requests").glob("*.json"))


def test_a_request_record_cannot_reach_outside_the_cache(cached, capsys, caplog):
    cache, victims = cached
    [record] = _records(cache)
    key = escaping_key("../../victims/")
    name = key.rsplit("/", 1)[1]
    # the victims: a manifest-looking file and its .npz, where the forged key points
    (victims / f"{name}.json").write_text('{"key": "not this one"}', encoding="utf-8")
    (victims / f"{name}.npz").write_bytes(b"precious")
    (victims / f"{name}.page").write_bytes(b"precious page")
    assert (cache / "motions" / f"{key}.npz").resolve() == (victims / f"{name}.npz").resolve()
    doc = json.loads(record.read_text(encoding="utf-8"))
    doc["motion"] = key
    record.write_text(json.dumps(doc), encoding="utf-8")
    tree = Tree(victims)
    outcome = run_cli(["solve", "--spec", SPEC, "--no-sim", "--quiet"], capsys)
    tree.assert_unchanged()
    assert outcome.code == 0, outcome.err
    assert "Traceback" not in outcome.err
    # the damaged record (inside the cache) was replaced by a healthy one
    [again] = _records(cache)
    assert json.loads(again.read_text(encoding="utf-8"))["motion"] != key


@pytest.mark.parametrize("key", ["/" + "a" * 63, "A" * 64, "g" * 64, "0" * 63 + "\n", "0" * 32 + ".." + "0" * 30],
                         ids=["absolute", "upper case", "not hex", "newline", "dots"])
def test_a_request_record_naming_no_key_is_damaged(cached, capsys, key):
    cache, _ = cached
    [record] = _records(cache)
    doc = json.loads(record.read_text(encoding="utf-8"))
    doc["motion"] = key
    record.write_text(json.dumps(doc), encoding="utf-8")
    outcome = run_cli(["solve", "--spec", SPEC, "--no-sim", "--quiet"], capsys)
    assert outcome.code == 0, outcome.err
    assert json.loads(_records(cache)[0].read_text(encoding="utf-8"))["motion"] != key
