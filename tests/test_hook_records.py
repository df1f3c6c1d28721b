"""The hook reads a skipped scene's waiting record (its manifest) once, for both the summary line
and the message that asks to commit the record."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from csm_assets.cli import main
from csm_assets.convert import lost_relief

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


def test_a_skipped_scene_s_record_is_read_once(tmp_path, monkeypatch, capsys):
    """Was: ``record_of`` (a manifest read) ran twice for a scene without relief whose record the
    hook wrote: once for the ``skipped`` line, once for the ``add it to the commit`` message."""
    doc = json.loads((SAMPLES / "brick_wall.gltf").read_text())
    doc["images"][1]["uri"] = "late_height.png"  # not there yet: the scene waits for it
    scene = tmp_path / "wall.gltf"
    scene.write_text(json.dumps(doc))
    shutil.copy(SAMPLES / "brick_wall.bin", tmp_path)
    shutil.copy(SAMPLES / "bricks_color.png", tmp_path)
    reads = []
    real = lost_relief.record_of
    monkeypatch.setattr(lost_relief, "record_of", lambda *a: reads.append(a) or real(*a))
    assert main(["hook", str(scene)]) == 1  # the record was written
    out, err = capsys.readouterr()
    assert f"{scene} (waiting for late_height.png)" in out, out
    assert "has no relief (waiting for late_height.png)" in err and "add it to the commit" in err, err
    assert len(reads) == 1, reads
