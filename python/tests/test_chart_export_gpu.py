"""read_chart on the development photographs (../shared/realcharts, ../shared/data/colorchart.dng),
equal to `nsrm chart extract --json`; export through the library's exporters; apply on the GPU."""

import json
import subprocess

import numpy as np
import pytest

import nsrm
from conftest import shared_dir, skip_or_fail

# (file, encoding, expected centres of 01, 06, 19, 24 in pixels: tests/all/chart_real.rs).
PHOTOS = [
    ("jtvd_classic_1.jpg", "auto", [[498, 1345], [476, 395], [1085, 1311], [1028, 369]]),
    ("pedrodiamel_scene.jpg", "auto", [[261, 303], [511, 303], [261, 453], [515, 442]]),
    ("jarrelscy_203500.jpg", "auto", [[1123, 980], [1123, 1815], [607, 974], [640, 1812]]),
    ("andriy_sun_linear8.tif", "linear", [[49, 50], [549, 51], [51, 349], [551, 348]]),
]


def photo(rel):
    p = shared_dir() / rel
    if not p.exists():
        skip_or_fail(f"{p} is absent (the development photographs stay outside the repository)")
    return p


def cli_reading(nsrm_bin, tmp_path, path, *args):
    out = subprocess.run(
        [nsrm_bin, "chart", "extract", str(path), "-o", str(tmp_path / "p.csv"), "--json",
         str(tmp_path / "r.json"), "--overwrite", *args],
        capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return json.loads((tmp_path / "r.json").read_text()), (tmp_path / "p.csv").read_text()


@pytest.mark.parametrize("name,encoding,want", PHOTOS, ids=[p[0] for p in PHOTOS])
def test_read_chart_on_the_real_photographs(tmp_path, nsrm_bin, name, encoding, want):
    path = photo(f"realcharts/{name}")
    r = nsrm.read_chart(path, "cc24", encoding=encoding)
    assert len(r["labels"]) == 24 and r["camera_rgb"].shape == (24, 3)
    assert r["corners"].shape == (4, 2)
    pitch = np.hypot(*(np.subtract(want[0], want[1]))) / 5
    for label, w in zip(["01 ", "06 ", "19 ", "24 "], want):
        i = next(i for i, l in enumerate(r["labels"]) if l.startswith(label))
        c = r["report"]["patches"][i]["centre"]
        assert np.hypot(c[0] - w[0], c[1] - w[1]) < 0.25 * pitch, (name, label, c, w)
    assert sum(r["usable"]) >= 8
    # The same reading as the command line's.
    report, csv = cli_reading(nsrm_bin, tmp_path, path, "--chart", "cc24", "--encoding", encoding)
    assert r["csv"] == csv
    assert r["report"]["patches"] == report["patches"]
    np.testing.assert_array_equal(r["corners"], np.array(report["corners"]))
    # Fit on the usable patches.
    t = r["training"]
    m = nsrm.fit(t["camera_rgb"], t["xyz"], "lrm", white=t["white_xyz"])
    assert m.apply(t["camera_rgb"]).shape == t["camera_rgb"].shape


def test_read_chart_on_the_dng(tmp_path, nsrm_bin):
    path = photo("data/colorchart.dng")
    r = nsrm.read_chart(path, "cc24")
    report, csv = cli_reading(nsrm_bin, tmp_path, path, "--chart", "cc24")
    assert r["csv"] == csv
    assert r["report"]["patches"] == report["patches"]
    assert sum(r["usable"]) >= 20
    t = r["training"]
    m = nsrm.fit(t["camera_rgb"], t["xyz"], "rprm", 2, white=t["white_xyz"])
    loo = nsrm.eval_loo(t["camera_rgb"], t["xyz"], "rprm", 2, white=t["white_xyz"])
    assert loo["mean"] < 5, loo["mean"]
    assert m.kind == "rprm"


def test_read_chart_takes_an_array(tmp_path, nsrm_bin):
    """An (H, W, 3 | 4) array of linear camera RGB is read as the linear file it came from."""
    scene = tmp_path / "scene.exr"
    out = subprocess.run([nsrm_bin, "render-scene", "--chart", "cc24", "--seed", "3", "-o",
                          str(scene)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    from_file = nsrm.read_chart(scene, "cc24")
    rgb = nsrm.read_frame(scene)
    from_array = nsrm.read_chart(rgb, "cc24")
    assert from_array["labels"] == from_file["labels"]
    np.testing.assert_array_equal(from_array["camera_rgb"], from_file["camera_rgb"])
    np.testing.assert_array_equal(from_array["corners"], from_file["corners"])
    rgba = np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 0.5, np.float32)], axis=2)
    np.testing.assert_array_equal(nsrm.read_chart(rgba.astype(np.float64))["camera_rgb"],
                                  from_file["camera_rgb"])
    with pytest.raises(nsrm.InputError, match=r"\(H, W, 3\)"):
        nsrm.read_chart(rgb.reshape(-1, 3))
    with pytest.raises(nsrm.InputError, match="file path"):
        nsrm.read_chart(np.zeros((4, 4, 2), np.float32))


def test_read_chart_errors(tmp_path):
    with pytest.raises(nsrm.NsrmError, match="nope.tif"):
        nsrm.read_chart(tmp_path / "nope.tif")
    with pytest.raises(nsrm.InputError):
        nsrm.read_chart(tmp_path / "x.tif", "cc99")


@pytest.mark.parametrize("fmt,suffix", [("clf", "clf"), ("cube", "cube"), ("ocio", "ocio"),
                                        ("dcp", "dcp"), ("icc", "icc")])
def test_export_writes_each_format(tmp_path, d65, fmt, suffix):
    m = nsrm.fit(d65["camera_rgb"], d65["xyz"], "rprm", 2, white=d65["white_xyz"],
                 white_rgb=d65["white_rgb"])
    out = tmp_path / f"m.{suffix}"
    r = nsrm.export(m, fmt, out, lut_size=33, dcp_map=(90, 30))
    assert out.exists() and out.stat().st_size > 0
    assert r["max_de00"] < 5, r["summary"]
    assert all(pathlib_exists(f) for f in r["files"])
    with pytest.raises(nsrm.NsrmError):
        nsrm.export(m, fmt, out, lut_size=33, dcp_map=(90, 30), overwrite=False)


def pathlib_exists(f):
    import os

    return os.path.exists(f)


def test_export_of_a_loaded_builtin_model_resimulates_its_patches(tmp_path, nsrm_bin):
    subprocess.run([nsrm_bin, "fit", "--kind", "lrm", "--reflectances", "cc24", "-o",
                    str(tmp_path / "m.json")], check=True, capture_output=True)
    m = nsrm.Model.load(tmp_path / "m.json")
    r = nsrm.export(m, "clf", tmp_path / "m.clf")
    assert r["max_de00"] < 1e-3  # an LRM is written exactly, as a Matrix
    with pytest.raises(nsrm.InputError, match="format"):
        nsrm.export(m, "png", tmp_path / "m.png")


def test_apply_on_the_gpu_matches_the_cpu_or_raises_clearly(d65):
    m = nsrm.fit(d65["camera_rgb"], d65["xyz"], "nsrm", 3, white=d65["white_xyz"])
    img = np.random.default_rng(2).uniform(0, 1, (64, 48, 4)).astype(np.float32)
    try:
        gpu = m.apply(img, device="gpu")
    except nsrm.GpuUnavailableError as e:
        assert "adapter" in str(e)
        skip_or_fail(f"no GPU adapter (not even lavapipe): {e}")
        return
    cpu = m.apply(img)
    np.testing.assert_array_equal(gpu[..., 3], img[..., 3])
    np.testing.assert_allclose(gpu, cpu, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("lang", ["dctl", "wgsl", "glsl", "hlsl", "msl", "spirv"])
def test_code_exports_equal_export_shader(tmp_path, nsrm_bin, d65, lang):
    m = nsrm.fit(d65["camera_rgb"], d65["xyz"], "nsrm", 3, white=d65["white_xyz"])
    m.save(tmp_path / "m.json")
    ours = tmp_path / f"ours.{lang}"
    r = nsrm.export(m, lang, ours, output_space="acescg", layout="rgba")
    assert r["files"] == [ours] and r["max_de00"] is None
    theirs = tmp_path / f"cli.{lang}"
    args = [nsrm_bin, "export-shader", "--model", str(tmp_path / "m.json"), "--lang", lang,
            "--output-space", "acescg", "-o", str(theirs)]
    if lang != "dctl":
        args += ["--layout", "rgba"]
    subprocess.run(args, check=True, capture_output=True)
    assert ours.read_bytes() == theirs.read_bytes()
