"""The pin of every built-in family's scene code version (``SceneEntry.version``) is safe: what each family builds
is fingerprinted in ``tests/scenes/scene_fingerprints.json`` beside its version (tools/scene_fingerprints.py;
rewrite with ``python -m tools.scene_fingerprints --update``)."""

from __future__ import annotations

import copy
import dataclasses
import json

import numpy as np
import pytest

from scenes.model import Box, SceneEntry
from scenes.registry import discover
from tools import scene_fingerprints as fp

FAMILIES = fp.builtin_families()


@pytest.mark.slow
def test_every_builtin_family_builds_what_its_fingerprints_record_under_its_version():
    problems = fp.check(fp.load(), FAMILIES)
    assert not problems, "\n".join(problems)


def test_every_builtin_family_declares_its_version_and_records_it():
    assert set(FAMILIES) == {n for n, e in discover()[0].items() if e.source.startswith("scenes/families/")}
    for name, entry in FAMILIES.items():
        assert entry.version.startswith("sha256:"), name
        assert entry.code_version == entry.version
        assert entry.build_spec(None, 0).code_version == entry.version


@pytest.fixture
def box_room():
    """The fast family, its fingerprints now, and a file holding them."""
    families = {"box_room": FAMILIES["box_room"]}
    return families, fp.compute(families)


def test_changed_scenes_under_the_same_version_fail_with_one_line_naming_family_version_and_command(box_room):
    families, now = box_room
    stored = copy.deepcopy(now)
    stored["box_room"]["scenes"]["hall@1"] = "sha256:0000000000000000"
    (msg,) = fp.check(stored, families, now)
    assert "\n" not in msg
    assert "'box_room'" in msg and "hall@1" in msg and "change its version" in msg and "refused" in msg
    assert "scenes/families/box_room.py" in msg and msg.endswith(fp.UPDATE_COMMAND)
    assert FAMILIES["box_room"].source_version in msg  # a new version to take
    stored = copy.deepcopy(now)
    stored["box_room"]["rigs"]["default@0"] = "sha256:0000000000000000"
    (msg,) = fp.check(stored, families, now)
    assert "rig placements of default@0" in msg and "change its version" in msg


def test_a_new_version_needs_rewritten_fingerprints(box_room):
    families, now = box_room
    bumped = {"box_room": dataclasses.replace(families["box_room"], version="sha256:1111111111111111")}
    (msg,) = fp.check(now, bumped, fp.compute(bumped))
    assert "declares version 'sha256:1111111111111111'" in msg and msg.endswith(fp.UPDATE_COMMAND)
    # changed scenes with a changed version: only the rewrite is asked for
    stored = copy.deepcopy(now)
    stored["box_room"]["scenes"]["hall@1"] = "sha256:0000000000000000"
    (msg,) = fp.check(stored, bumped, fp.compute(bumped))
    assert "rewrite the fingerprints" in msg and "change its version" not in msg


def test_missing_unknown_and_undeclared_families_fail(box_room):
    families, now = box_room
    (msg,) = fp.check({}, families, now)
    assert "'box_room' has no fingerprints" in msg and msg.endswith(fp.UPDATE_COMMAND)
    (msg,) = fp.check({**now, "attic": now["box_room"]}, families, now)
    assert "'attic', which is no built-in scene family" in msg and msg.endswith(fp.UPDATE_COMMAND)
    unversioned = {"box_room": dataclasses.replace(families["box_room"], version="")}
    (msg,) = fp.check(now, unversioned, now)
    assert "declares no version" in msg


def test_update_refuses_changed_scenes_under_the_same_version_unless_forced(tmp_path, box_room):
    families, now = box_room
    path = tmp_path / "fingerprints.json"
    assert fp.update(path, families) == []
    assert fp.load(path) == now
    data = json.loads(path.read_text())
    data["families"]["box_room"]["scenes"]["small@7"] = "sha256:0000000000000000"
    path.write_text(json.dumps(data))
    before = path.read_text()
    (msg,) = fp.update(path, families)
    assert "change its version" in msg and path.read_text() == before
    assert fp.update(path, families, force=True) == [] and fp.load(path) == now
    # a bumped version is rewritten without force
    data["families"]["box_room"]["scenes"]["small@7"] = "sha256:0000000000000000"
    path.write_text(json.dumps(data))
    bumped = {"box_room": dataclasses.replace(families["box_room"], version="sha256:1111111111111111")}
    assert fp.update(path, bumped) == [] and fp.load(path)["box_room"]["version"] == "sha256:1111111111111111"


def test_fingerprints_ignore_last_bit_float_differences_and_int_versus_float():
    x = 1.2345678901234567
    assert fp.canonical([x, -0.0, 3e-17, 2]) == fp.canonical([np.nextafter(x, 2.0), 0.0, -2e-17, 2.0])
    assert fp.canonical(True) is True and fp.canonical(np.float32(0.5)) == 0.5
    a = Box(center=(1.0, 2.0, 0.1 + 0.2), size=(1, 1, 1), material="m")
    b = Box(center=(1.0, 2.0, 0.3), size=(1.0, 1.0, 1.0), material="m")
    assert fp.canonical(a) == fp.canonical(b)
    assert fp.canonical(a) != fp.canonical(dataclasses.replace(b, center=(1.0, 2.0, 0.30001)))


def test_an_outside_family_without_a_version_keeps_the_source_hash():
    entry = SceneEntry(name="outside", build=FAMILIES["box_room"].build)
    assert entry.version == "" and entry.code_version == entry.source_version
    assert entry.source_version.startswith("sha256:") and entry.source_version != FAMILIES["box_room"].version
    with pytest.raises(ValueError, match="version must be a string without spaces"):
        SceneEntry(name="outside", build=FAMILIES["box_room"].build, version="v 2")
