"""Output size against input size for compressed and quantized glTF: ``python benchmarks/compressed_size.py``.

Makes a UV sphere (the tests' ``uv_sphere`` with its one real uv set as TEXCOORD_0, as most
assets have it: 1,225 and 51,681 vertices, the sample bricks' heights) and the sample brick
wall, then with the real tools (tests/gltf_tools.py: gltf-pipeline 4.3 ``-d`` Draco GLB,
gltfpack 1.3 ``-cc`` meshopt GLB and its default quantized .gltf) the compressed inputs,
converts each with ``csm-assets convert`` (the one on ``PYTHONPATH``, so an older checkout can
be measured alike; run it from outside the checkout then) and prints a Markdown table: the
input's bytes (scene file and buffers), the output's (scene file and buffers; the step map PNG
and copied images apart, in ``maps``), their ratio, and the compression the output declares.
docs/measurements/compressed-inputs.md holds the figures.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the tests' sphere and tool wrappers
sys.path.insert(0, str(ROOT))

from csm_assets.formats import gltf_container as gc  # noqa: E402
from gltf_tools import draco, gltfpack  # noqa: E402
from test_gltf_compressed import uv_sphere  # noqa: E402

SAMPLES = ROOT / "samples"
PACKED = ("KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_mesh_quantization")


def scene_bytes(path: Path) -> int:
    doc = gc.load(path)
    return path.stat().st_size + sum(f.stat().st_size for f in doc.files)


def one_uv_set(path: Path) -> Path:
    """The tests' sphere (a dummy TEXCOORD_0, the real uvs in TEXCOORD_1) with only the real uvs, as TEXCOORD_0."""
    doc = json.loads(path.read_text())
    attrs = doc["meshes"][0]["primitives"][0]["attributes"]
    attrs["TEXCOORD_0"] = attrs.pop("TEXCOORD_1")
    for info in (doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"],
                 doc["materials"][0]["extensions"]["KHR_materials_displacement"]["displacementGeometryTexture"]):
        info["texCoord"] = 0
    path.write_text(json.dumps(doc))
    return path


def inputs(work: Path) -> list[tuple[str, Path]]:
    for name in ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, work / name)
    scenes = [("wall (4 vertices)", work / "brick_wall.gltf"),
              ("sphere (1,225 vertices)", one_uv_set(uv_sphere(work / "sphere.gltf"))),
              ("sphere (51,681 vertices)", one_uv_set(uv_sphere(work / "big.gltf", rings=160, segments=320)))]
    out = []
    for label, plain in scenes:
        out += [(f"{label}, plain", plain),
                (f"{label}, Draco GLB", draco(plain, plain.with_name(f"{plain.stem}_draco.glb"))),
                (f"{label}, meshopt GLB", gltfpack(plain, plain.with_name(f"{plain.stem}_mo.glb"), "-cc")),
                (f"{label}, quantized", gltfpack(plain, plain.with_name(f"{plain.stem}_q.gltf")))]
    return out


def main() -> int:
    work = Path(tempfile.mkdtemp(prefix="csm-size-"))
    try:
        print("| scene | input bytes | output bytes | out / in | maps, images | still |")
        print("| --- | --- | --- | --- | --- | --- |")
        for label, src in inputs(work):
            out = work / f"out_{src.stem}"
            r = subprocess.run([sys.executable, "-m", "csm_assets", "convert", str(src), "-o", str(out), "--height",
                                f"bricks={work / 'bricks_height.png'}", "--ignore", "CSM205"],
                               capture_output=True, text=True)
            if r.returncode:
                sys.exit(f"{src.name}: {r.stderr}")
            written = out / src.name
            size_in, size_out = scene_bytes(src), scene_bytes(written)
            maps = sum(f.stat().st_size for f in out.iterdir() if f.suffix in (".png", ".jpg"))
            if src.suffix == ".glb":  # the step map lies in the GLB: count it with the maps
                doc = gc.load(written)
                maps += sum(doc.json["bufferViews"][im["bufferView"]]["byteLength"]
                            for im in doc.json.get("images", []) if im.get("name", "").endswith("_csm"))
                size_out -= maps
            kept = [e for e in PACKED if e in json.loads(gc.gltf_bytes(gc.load(written))).get("extensionsUsed", [])]
            print(f"| {label} | {size_in:,} | {size_out:,} | {size_out / size_in:.2f} | {maps:,} | "
                  f"{', '.join(e.split('_', 1)[1] for e in kept) or '-'} |")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
