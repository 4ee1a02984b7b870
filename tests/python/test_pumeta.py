"""The Python module: upsampling, files, metrics and its errors (ctest "python").

Run with PYTHONPATH=build/python python3 -m pytest tests/python.
"""
import math
import os

import numpy as np
import pytest

import pumeta


def sphere(n):
    """n points spread evenly over the unit sphere (a Fibonacci lattice), float32 [n,3]."""
    i = np.arange(n)
    z = 1.0 - (2.0 * i + 1.0) / n
    r = np.sqrt(1.0 - z * z)
    angle = math.pi * (3.0 - math.sqrt(5.0)) * i
    return np.stack([r * np.cos(angle), r * np.sin(angle), z], axis=1).astype(np.float32)


def cube_corners():
    return np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float32)


def brute_force_chamfer(a, b):
    d = ((a[:, None, :].astype(np.float64) - b[None, :, :]) ** 2).sum(axis=2)
    return d.min(axis=1).mean() + d.min(axis=0).mean()


# Upsampling


def test_upsample_gives_ratio_times_the_points_closer_to_the_surface():
    points = sphere(512)
    dense = pumeta.upsample(points)
    assert dense.shape == (2048, 3)
    assert dense.dtype == np.float32
    assert np.isfinite(dense).all()
    surface = sphere(8192)
    cd_input = pumeta.metrics(points, surface)["cd"]
    cd_output = pumeta.metrics(dense, surface)["cd"]
    assert cd_output < cd_input


def test_upsample_converts_float64_and_lists():
    points = sphere(300)
    expected = pumeta.upsample(points)
    np.testing.assert_array_equal(pumeta.upsample(points.astype(np.float64)), expected)
    np.testing.assert_array_equal(pumeta.upsample(points.tolist()), expected)


def test_upsample_ratio_picks_the_model_and_adaptation_follows_the_seed():
    points = sphere(256)
    assert pumeta.upsample(points, ratio=8).shape == (2048, 3)
    model = os.path.join(pumeta_models(), "pugcn-x4.pt")
    adapted = pumeta.upsample(points, model=model, tta_steps=1, tta_lr=1e-3, seed=3)
    again = pumeta.upsample(points, model=model, tta_steps=1, tta_lr=1e-3, seed=3)
    plain = pumeta.upsample(points, model=model)
    assert adapted.shape == (1024, 3)
    np.testing.assert_array_equal(adapted, again)
    assert not np.array_equal(adapted, plain)


def pumeta_models():
    here = os.path.dirname(os.path.abspath(__file__))
    return os.environ.get("PUMETA_MODELS", os.path.join(here, "..", "..", "models"))


# Files


@pytest.mark.parametrize("extension", ["ply", "pcd", "xyz"])
def test_write_then_read_gives_the_points_back(tmp_path, extension):
    points = np.random.default_rng(1).normal(size=(100, 3)).astype(np.float32)
    path = tmp_path / f"cloud.{extension}"
    pumeta.write(path, points)
    back = pumeta.read(str(path))
    assert back.dtype == np.float32
    if extension == "xyz":  # text
        np.testing.assert_allclose(back, points, rtol=1e-6, atol=1e-6)
    else:
        np.testing.assert_array_equal(back, points)


# Metrics


def test_identical_clouds_score_zero():
    points = sphere(200)
    m = pumeta.metrics(points, points)
    assert m["cd"] == 0 and m["hd"] == 0 and m["hd_legacy"] == 0
    assert m["psnr"] == math.inf
    assert m["p2f"] is None
    assert (m["n_pred"], m["n_gt"]) == (200, 200)


def test_shifted_copy_gives_the_analytic_values():
    # Cube corners moved by d = 0.1 along x: each corner's nearest point is its own copy. The
    # GT frame divides by the corners' radius sqrt(3); PSNR scales GT's longest side (2) to p.
    gt = cube_corners()
    pred = gt + np.float32([0.1, 0, 0])
    m = pumeta.metrics(pred, gt)
    assert m["cd"] == pytest.approx(2 * 0.01 / 3, rel=1e-5)
    in_frame = brute_force_chamfer(pred / math.sqrt(3), gt / math.sqrt(3))
    assert m["cd"] == pytest.approx(in_frame, rel=1e-5)
    assert m["hd"] == pytest.approx(0.1 / math.sqrt(3), rel=1e-5)
    assert m["hd_legacy"] == pytest.approx(2 * 0.01 / 3, rel=1e-5)
    assert m["psnr"] == pytest.approx(10 * math.log10(3 * 2**2 / 0.1**2), rel=1e-5)


def test_point_to_face_distance_against_a_mesh_file(tmp_path):
    # The square [-1,1]^2 at z = 0, points 0.05 above it; GT = the square's corners and centre
    # (radius sqrt(2) from their bounding-box centre).
    mesh = tmp_path / "square.off"
    mesh.write_text("OFF\n4 2 0\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n3 0 1 2\n3 0 2 3\n")
    gt = np.float32([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0], [0, 0, 0]])
    pred = np.float32([[0.5, 0.5, 0.05], [-0.3, 0.2, 0.05], [0, -0.9, 0.05]])
    m = pumeta.metrics(pred, gt, mesh=str(mesh))
    assert m["p2f"] == pytest.approx(0.05 / math.sqrt(2), rel=1e-5)


# Errors: the command line's one-line message, as ValueError or OSError


def test_a_missing_file_is_an_oserror_naming_it(tmp_path):
    path = str(tmp_path / "missing.ply")
    with pytest.raises(OSError, match="missing.ply: file not found"):
        pumeta.read(path)
    with pytest.raises(OSError, match="missing.ply"):
        pumeta.upsample(sphere(64), model=path)
    with pytest.raises(OSError, match="missing.ply"):
        pumeta.metrics(sphere(8), sphere(8), mesh=path)
    with pytest.raises(OSError, match="no-such-dir"):
        pumeta.write(tmp_path / "no-such-dir" / "out.ply", sphere(8))


def test_a_garbage_file_is_a_valueerror_naming_it(tmp_path):
    path = tmp_path / "garbage.ply"
    path.write_bytes(b"this is not a ply file\n\x00\x01\x02")
    with pytest.raises(ValueError, match="garbage.ply: ") as error:
        pumeta.read(path)
    assert "\n" not in str(error.value)
    with pytest.raises(ValueError, match="garbage.ply: "):
        pumeta.upsample(sphere(64), model=str(path))


@pytest.mark.parametrize(
    "points, message",
    [
        (np.zeros((10, 2), np.float32), r"shape \[N,3\], found shape \(10, 2\)"),
        (np.zeros(30, np.float32), r"shape \[N,3\], found shape \(30,\)"),
        (np.zeros((0, 3), np.float32), "at least 1"),
        (np.array([["a", "b", "c"]]), "real numbers"),
        (None, "real numbers"),
    ],
)
def test_wrong_points_are_a_valueerror(points, message):
    with pytest.raises(ValueError, match=message):
        pumeta.upsample(points)


def test_non_finite_points_are_a_valueerror(tmp_path):
    points = sphere(64)
    points[5, 1] = np.nan
    with pytest.raises(ValueError, match="NaN or infinite coordinates .*row 5"):
        pumeta.upsample(points)
    with pytest.raises(ValueError, match="NaN or infinite"):
        pumeta.metrics(points, sphere(64))
    with pytest.raises(ValueError, match="NaN or infinite"):
        pumeta.write(tmp_path / "out.ply", points)
    assert not (tmp_path / "out.ply").exists()


def test_a_ratio_the_model_cannot_serve_is_a_valueerror():
    with pytest.raises(ValueError, match="ratio 3 is not a power of the model's ratio 4"):
        pumeta.upsample(sphere(64), ratio=3)
    with pytest.raises(ValueError, match="ratio"):
        pumeta.upsample(sphere(64), ratio=-2)
    with pytest.raises(ValueError, match="tta_lr"):
        pumeta.upsample(sphere(64), tta_steps=1, tta_lr=0.0)


def test_an_unknown_extension_is_a_valueerror(tmp_path):
    with pytest.raises(ValueError, match="out.abc"):
        pumeta.write(tmp_path / "out.abc", sphere(8))
