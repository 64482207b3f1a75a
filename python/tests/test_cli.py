"""The bindings against the `nsrm` command line: `Model.apply` equals `nsrm apply --device cpu`
bit for bit, models round-trip between the two, `eval_loo` equals `nsrm eval --json`."""

import json
import subprocess

import numpy as np
import pytest

import nsrm

tifffile = pytest.importorskip("tifffile")


def run(*args, cwd=None):
    out = subprocess.run(args, cwd=cwd, capture_output=True, text=True)
    assert out.returncode == 0, f"{args}: {out.stderr}"
    return out


def awkward_frame(rng, h, w, channels):
    """A frame with what the pixel policy covers: ordinary values, highlights, darks,
    negatives, zeros, NaN and ±Inf."""
    img = rng.uniform(0.0, 1.2, (h, w, channels)).astype(np.float32)
    img[0, :5, :3] = [[np.nan, 0.2, 0.3], [np.inf, 0.1, 0.1], [-np.inf, 0, 0], [0, 0, 0],
                      [-0.1, -0.2, -0.05]]
    img[1, :3, :3] = [[4.0, 3.0, 2.0], [1e-8, 1e-8, 1e-8], [1e6, 1e6, 1e6]]
    if channels == 4:
        img[..., 3] = rng.uniform(0, 1, (h, w))
    return img


def bits(a):
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)


@pytest.mark.parametrize("kind,order", [("lrm", 1), ("prm", 3), ("rprm", 3), ("nsrm", 3),
                                        ("nsrm", 2), ("prm", 4)])
@pytest.mark.parametrize("space", ["xyz", "acescg"])
def test_apply_equals_the_cli_bit_for_bit(tmp_path, nsrm_bin, d65, kind, order, space):
    rng = np.random.default_rng(order * 10 + len(kind))
    # PRM 4 (34 terms, the generic "plan" kernel) needs more patches than the 24.
    d = d65 if order < 4 else nsrm.builtin_training("nikon-d5100", "D65", "rawtoaces-190")
    m = nsrm.fit(d["camera_rgb"], d["xyz"], kind, order, white=d["white_xyz"])
    model_path = tmp_path / "m.json"
    m.save(model_path)
    for channels in (3, 4):
        img = awkward_frame(rng, 37, 53, channels)
        src = tmp_path / f"in{channels}.tif"
        tifffile.imwrite(src, img, photometric="rgb",
                         extrasamples=["unassalpha"] if channels == 4 else None)
        out_dir = tmp_path / f"out{channels}"
        run(nsrm_bin, "apply", "--model", str(model_path), "--device", "cpu", "--format", "tiff",
            "--output-space", space, "-o", str(out_dir), str(src))
        (written,) = list(out_dir.glob("*.tif*"))
        cli = tifffile.imread(written)
        ours = m.apply(img, output_space=space)
        assert cli.shape == ours.shape, (cli.shape, ours.shape)
        np.testing.assert_array_equal(bits(cli), bits(ours))
        # The model loaded back from the file: the same bits too.
        np.testing.assert_array_equal(bits(nsrm.Model.load(model_path).apply(img, output_space=space)),
                                      bits(ours))


def test_highlight_clip_equals_the_cli(tmp_path, nsrm_bin, d65):
    m = nsrm.fit(d65["camera_rgb"], d65["xyz"], "rprm", 3, white=d65["white_xyz"])
    m.save(tmp_path / "m.json")
    img = awkward_frame(np.random.default_rng(5), 20, 30, 3)
    tifffile.imwrite(tmp_path / "in.tif", img, photometric="rgb")
    run(nsrm_bin, "apply", "--model", str(tmp_path / "m.json"), "--device", "cpu", "--format",
        "tiff", "--highlights", "clip", "--clip-level", "1.0", "-o", str(tmp_path / "o"),
        str(tmp_path / "in.tif"))
    (written,) = list((tmp_path / "o").glob("*.tif*"))
    ours = m.apply(img, highlights="clip", clip_level=1.0)
    np.testing.assert_array_equal(bits(tifffile.imread(written)), bits(ours))
    assert not np.array_equal(bits(ours), bits(m.apply(img)))


def test_cli_model_loads_and_applies_the_same(tmp_path, nsrm_bin, d65):
    run(nsrm_bin, "fit", "--kind", "nsrm", "--order", "3", "--reflectances", "cc24", "-o",
        str(tmp_path / "cli.json"))
    cli_model = nsrm.Model.load(tmp_path / "cli.json")
    ours = nsrm.fit(d65["camera_rgb"], d65["xyz"], "nsrm", 3, white=d65["white_xyz"])
    assert cli_model.terms == ours.terms
    np.testing.assert_allclose(cli_model.matrix, ours.matrix, rtol=1e-12, atol=1e-12)


def test_eval_loo_equals_cli_eval_json(nsrm_bin):
    out = run(nsrm_bin, "eval", "--json", "--illuminant", "D65", "--order", "3")
    cli = {}
    for r in json.loads(out.stdout)["results"]:
        cli.setdefault(r["model"], r)
    d = nsrm.builtin_training("nikon-d5100", "D65", "rawtoaces-190")
    for kind in ("lrm", "prm", "rprm", "nsrm"):
        r = nsrm.eval_loo(d["camera_rgb"], d["xyz"], kind, 3, white=d["white_xyz"],
                          labels=d["labels"])
        c = cli[kind.upper()] if kind.upper() in cli else cli[kind]
        for k in ("mean", "median", "p95", "max"):
            assert r[k] == pytest.approx(c[k], rel=1e-12, abs=1e-12), (kind, k)
        per = [p["dE00"] for p in c["per_patch"]]
        np.testing.assert_allclose(r["per_patch"], per, rtol=1e-12, atol=1e-12)
        assert r["labels"] == [p["label"] for p in c["per_patch"]]


def test_read_frame_reads_what_apply_reads(tmp_path, d65):
    img = np.random.default_rng(9).uniform(0, 2, (11, 13, 3)).astype(np.float32)
    tifffile.imwrite(tmp_path / "f.tif", img, photometric="rgb")
    back = nsrm.read_frame(tmp_path / "f.tif")
    assert back.shape == img.shape and back.dtype == np.float32
    np.testing.assert_array_equal(back, img)
    with pytest.raises(nsrm.NsrmError):
        nsrm.read_frame(tmp_path / "missing.exr")
