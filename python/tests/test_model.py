"""nsrm.fit, nsrm.Model: fit, apply on the CPU, the model file, the arrays it takes."""

import numpy as np
import pytest

import nsrm


def fit_d65(d, kind="nsrm", order=3, **kw):
    return nsrm.fit(
        d["camera_rgb"], d["xyz"], kind, order, white=d["white_xyz"], white_rgb=d["white_rgb"], **kw
    )


def test_fit_predicts_the_training_patches(d65):
    m = fit_d65(d65)
    assert m.kind == "nsrm" and m.order == 3
    assert m.matrix.shape == (3, len(m.terms))
    assert m.matrix.dtype == np.float64
    # In-sample: the f64 reference prediction is close to the reference XYZ.
    pred = m.apply_f64(d65["camera_rgb"])
    assert pred.shape == (24, 3)
    err = np.abs(pred - d65["xyz"]).max()
    assert err < 5.0, err
    assert m.fit_report["objective"] == "ls"


def test_apply_is_xyz_relative_to_white_and_float32(d65):
    m = fit_d65(d65, "rprm", 2)
    rgb = d65["camera_rgb"].astype(np.float32)
    out = m.apply(rgb)
    assert out.dtype == np.float32 and out.shape == rgb.shape
    # `nsrm apply` writes XYZ with the training white at Y = 1: the reference divided by its Y.
    ref = m.apply_f64(d65["camera_rgb"]) / m.white_xyz[1]
    np.testing.assert_allclose(out, ref, rtol=1e-4, atol=1e-5)


def test_apply_shapes_alpha_dtypes_and_non_contiguous(d65, rng):
    m = fit_d65(d65)
    img = rng.uniform(0, 1, (5, 7, 4)).astype(np.float32)
    out = m.apply(img)
    assert out.shape == img.shape
    np.testing.assert_array_equal(out[..., 3], img[..., 3])  # alpha untouched
    rgb = np.ascontiguousarray(img[..., :3])
    np.testing.assert_array_equal(out[..., :3], m.apply(rgb))
    # float64 in: the same f32 computation.
    np.testing.assert_array_equal(m.apply(rgb.astype(np.float64)), m.apply(rgb))
    # A non-contiguous view is copied, the result the same.
    view = img[:, ::2, :3]
    assert not view.flags["C_CONTIGUOUS"]
    np.testing.assert_array_equal(m.apply(view), m.apply(np.ascontiguousarray(view)))
    # Fortran order (contiguous, but not C order): converted, the same result.
    for a in (img, img.astype(np.float64)):
        np.testing.assert_array_equal(m.apply(np.asfortranarray(a)), out)
    # One pixel, and a list.
    np.testing.assert_array_equal(m.apply(rgb[0, 0]), m.apply(rgb[:1, :1])[0, 0])
    np.testing.assert_array_equal(m.apply(rgb[0, 0].tolist()), m.apply(rgb[0, 0]))


def test_pixel_policy_nan_propagates_and_dark_nsrm_is_zero(d65):
    m = fit_d65(d65)
    px = np.array([[np.nan, 0.2, 0.3], [0.0, 0.0, 0.0], [-1.0, -1.0, -1.0]], np.float32)
    out = m.apply(px)
    assert np.isnan(out[0]).any()
    np.testing.assert_array_equal(out[1:], 0.0)


def test_hostile_arrays_raise_input_errors(d65):
    m = fit_d65(d65)
    with pytest.raises(nsrm.InputError, match="expected"):
        m.apply(np.zeros((4, 5), np.float32))
    with pytest.raises(nsrm.InputError, match="dtype"):
        m.apply(np.zeros((4, 3), np.int32))
    with pytest.raises(nsrm.InputError, match="max_pixels"):
        m.apply(np.zeros((10, 3), np.float32), max_pixels=5)
    # A huge array is refused before anything is allocated (a broadcast view: no memory).
    huge = np.broadcast_to(np.float32(0.5), (1 << 20, 1 << 10, 3))
    with pytest.raises(nsrm.InputError, match="max_pixels"):
        m.apply(huge)
    with pytest.raises(ValueError, match="device"):
        m.apply(np.zeros((1, 3), np.float32), device="tpu")
    bad = d65["camera_rgb"].copy()
    bad[3, 1] = np.nan
    with pytest.raises(nsrm.InputError, match="not finite"):
        nsrm.fit(bad, d65["xyz"], white="D65")
    with pytest.raises(nsrm.InputError, match="white"):
        nsrm.fit(d65["camera_rgb"], d65["xyz"])
    with pytest.raises(nsrm.InputError, match="rows"):
        nsrm.fit(d65["camera_rgb"][:5], d65["xyz"], white="D65")
    with pytest.raises(nsrm.NsrmError):
        nsrm.fit(d65["camera_rgb"], d65["xyz"], "ccm", white="D65")
    with pytest.raises(nsrm.NsrmError):
        nsrm.fit(d65["camera_rgb"][:4], d65["xyz"][:4], "nsrm", 3, white="D65")
    assert issubclass(nsrm.InputError, nsrm.NsrmError)
    assert issubclass(nsrm.InputError, ValueError)
    assert issubclass(nsrm.GpuUnavailableError, RuntimeError)


def test_save_load_round_trip(tmp_path, d65):
    m = fit_d65(d65, objective="de00", preserve_white=True, ridge="auto")
    p = tmp_path / "m.json"
    m.save(p)
    back = nsrm.Model.load(p)
    assert back.terms == m.terms and back.kind == m.kind and back.order == m.order
    np.testing.assert_array_equal(back.matrix, m.matrix)
    assert back.to_json() == m.to_json()
    with pytest.raises(nsrm.InputError):
        m.save(p, overwrite=False)
    with pytest.raises(nsrm.NsrmError, match="m2.json"):
        nsrm.Model.load(tmp_path / "m2.json")


def test_fit_options_reach_the_library(d65):
    m = fit_d65(d65, "prm", 2, preserve_white=True)
    w = m.apply_f64(np.array(d65["white_rgb"]))
    np.testing.assert_allclose(w, d65["white_xyz"], rtol=1e-9)
    r = fit_d65(d65, ridge=0.5).fit_report
    assert r["ridge_lambda"] == 0.5
    with pytest.raises(nsrm.InputError):
        fit_d65(d65, ridge=-1)
    wb = fit_d65(d65, normalise="white-balanced")
    assert wb.input_gains != (1.0, 1.0, 1.0)


def test_delta_e00_is_vectorised():
    lab1 = np.array([[50.0, 2.6772, -79.7751], [50.0, 3.1571, -77.2803]])
    lab2 = np.array([[50.0, 0.0, -82.7485], [50.0, 0.0, -82.7485]])
    de = nsrm.delta_e00(lab1, lab2)
    # Sharma, Wu & Dalal's first two pairs.
    np.testing.assert_allclose(de, [2.0425, 2.8615], atol=1e-4)
    assert nsrm.delta_e00(lab1.reshape(2, 1, 3), lab2.reshape(2, 1, 3)).shape == (2, 1)
    # Broadcasting: every row of lab1 against one colour; (2, 1, 3) against (4, 3).
    np.testing.assert_array_equal(nsrm.delta_e00(lab1, lab2[0]), de)
    assert nsrm.delta_e00(lab1.reshape(2, 1, 3), np.zeros((4, 3))).shape == (2, 4)
    with pytest.raises(nsrm.InputError):
        nsrm.delta_e00(lab1, np.zeros((3, 3)))


def test_apply_into_out(d65, rng):
    m = fit_d65(d65)
    img = rng.uniform(0, 1, (6, 5, 4)).astype(np.float32)
    want = m.apply(img)
    for src in (img, img.astype(np.float64), np.asfortranarray(img)):
        out = np.full(img.shape, 7.0, np.float32)
        got = m.apply(src, out=out)
        assert got is out
        np.testing.assert_array_equal(out, want)
    with pytest.raises(nsrm.InputError, match="not the input"):
        m.apply(img, out=img)
    with pytest.raises(nsrm.InputError, match="shape"):
        m.apply(img, out=np.zeros((6, 5, 3), np.float32))
    with pytest.raises(nsrm.InputError, match="float32"):
        m.apply(img, out=np.zeros(img.shape, np.float64))
    with pytest.raises(nsrm.InputError, match="C-contiguous"):
        m.apply(img[:, :2], out=np.zeros((6, 4, 4), np.float32)[:, ::2])
    ro = np.zeros(img.shape, np.float32)
    ro.flags.writeable = False
    with pytest.raises(nsrm.InputError):
        m.apply(img, out=ro)


def test_apply_releases_the_gil(d65):
    """While another thread corrects a large frame four times, this thread keeps running
    Python: it is running (steps under 2 ms apart) for a good part of that time. With the GIL
    held by apply it could only run between the applies."""
    import threading
    import time

    m = fit_d65(d65)
    big = np.random.default_rng(0).uniform(0, 1, (3000, 4000, 3)).astype(np.float32)
    th = threading.Thread(target=lambda: [m.apply(big) for _ in range(4)])
    running = 0.0
    t0 = last = time.perf_counter()
    th.start()
    while th.is_alive():
        now = time.perf_counter()
        if now - last < 0.002:
            running += now - last
        last = now
    th.join()
    share = running / (last - t0)
    # Measured on 2 busy cores: 0.33 here; 0.06 for numpy's tobytes, which holds the GIL.
    assert share > 0.15, share
