"""Loading engine images as candidates: channel layouts, PNG decoding, one-line errors."""

import struct
import zlib

import numpy as np
import OpenEXR
import pytest
from PIL import Image
from raster_oracle.metrics import srgb_decode
from raster_oracle.oracle.reference.exr import write_exr
from raster_oracle.oracle.scoring.inputs.candidates import CandidateError
from raster_oracle.oracle.scoring.inputs.layout import load_candidate

H, W = 6, 10
# 8-bit PNG values decoded in float32: exact up to float32 rounding of the sRGB curve.
PNG_ATOL = 1e-6


@pytest.fixture
def rgb():
    return np.random.default_rng(0).random((H, W, 3)).astype(np.float32)


def _write_png_raw(path, array, bit_depth, colour_type):
    """Minimal PNG writer (filter 0 on every row), for files Pillow cannot write."""
    h = array.shape[0]
    rows = array.astype(">u2" if bit_depth == 16 else "u1").reshape(h, -1)
    data = b"".join(b"\x00" + row.tobytes() for row in rows)

    def chunk(kind, payload):
        crc = zlib.crc32(kind + payload) & 0xFFFFFFFF
        return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", crc)

    ihdr = struct.pack(">IIBBBBB", array.shape[1], h, bit_depth, colour_type, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(data))
        + chunk(b"IEND", b"")
    )


# --------------------------------------------------------------------------- EXR layouts


def test_exr_rgb(tmp_path, rgb):
    path = tmp_path / "c.exr"
    write_exr(path, {"R": rgb[..., 0], "G": rgb[..., 1], "B": rgb[..., 2], "A": rgb[..., 0]})
    out = load_candidate(path, expected_shape=(H, W))
    assert out.dtype == np.float32 and out.shape == (H, W, 3)
    np.testing.assert_array_equal(out, rgb)


def test_exr_color_layer_is_preferred(tmp_path, rgb):
    path = tmp_path / "c.exr"
    layers = {f"color.{c}": rgb[..., i] for i, c in enumerate("RGB")}
    write_exr(path, {**layers, "R": rgb[..., 0] * 0, "G": rgb[..., 1] * 0, "B": rgb[..., 2] * 0})
    np.testing.assert_array_equal(load_candidate(path, channel="color"), rgb)


def test_exr_single_other_layer_and_named_layer(tmp_path, rgb):
    path = tmp_path / "c.exr"
    write_exr(path, {f"beauty.{c}": rgb[..., i] for i, c in enumerate("RGB")} | {"Z": rgb[..., 0]})
    np.testing.assert_array_equal(load_candidate(path), rgb)
    np.testing.assert_array_equal(load_candidate(path, channel="beauty"), rgb)
    np.testing.assert_array_equal(load_candidate(path, channel="beauty.G"), rgb[..., 1])
    np.testing.assert_array_equal(load_candidate(path, channel="Z"), rgb[..., 0])


def test_exr_luminance_only(tmp_path, rgb):
    path = tmp_path / "c.exr"
    write_exr(path, {"Y": rgb[..., 1]})
    color = load_candidate(path)
    assert color.shape == (H, W, 3)
    np.testing.assert_array_equal(color[..., 2], rgb[..., 1])
    np.testing.assert_array_equal(load_candidate(path, channel="visibility"), rgb[..., 1])


def test_exr_visibility_layouts(tmp_path, rgb):
    vis = rgb[..., 0]
    cases = {
        "named.exr": {"visibility": vis, "R": vis * 0, "G": vis * 0, "B": vis * 0},
        "layer.exr": {"shadow.visibility": vis, "A": vis},
        "lone.exr": {"V": vis},
        "grey_rgb.exr": {"R": vis, "G": vis, "B": vis},
    }
    for name, chans in cases.items():
        write_exr(tmp_path / name, chans)
        out = load_candidate(tmp_path / name, channel="visibility", expected_shape=(H, W))
        np.testing.assert_array_equal(out, vis, err_msg=name)


def test_exr_half_and_uint_channels(tmp_path, rgb):
    path = tmp_path / "half.exr"
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    ids = np.arange(H * W, dtype=np.uint32).reshape(H, W)
    with OpenEXR.File(header, {"RGB": rgb.astype(np.float16), "id": ids}) as f:
        f.write(str(path))
    out = load_candidate(path)
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, rgb.astype(np.float16).astype(np.float32))
    np.testing.assert_array_equal(load_candidate(path, channel="id"), ids.astype(np.float32))


# --------------------------------------------------------------------------- PNG


def test_png_8bit_rgb_is_srgb_decoded(tmp_path):
    values = np.random.default_rng(1).integers(0, 256, (H, W, 4), dtype=np.uint8)
    path = tmp_path / "c.png"
    Image.fromarray(values).save(path)
    out = load_candidate(path, expected_shape=(H, W))
    assert out.shape == (H, W, 3) and out.dtype == np.float32
    expected = srgb_decode(values[..., :3].astype(np.float32) / 255)
    np.testing.assert_allclose(out, expected, atol=PNG_ATOL)


def test_png_grey_visibility_is_data_not_decoded(tmp_path):
    values = np.arange(H * W, dtype=np.uint8).reshape(H, W) * 4
    path = tmp_path / "v.png"
    Image.fromarray(values).save(path)
    vis = load_candidate(path, channel="visibility")
    np.testing.assert_array_equal(vis, values.astype(np.float32) / np.float32(255))
    colour = load_candidate(path, channel="color")  # the same file read as colour is decoded
    np.testing.assert_allclose(colour[..., 0], srgb_decode(vis), atol=PNG_ATOL)


def test_png_16bit_grey(tmp_path):
    values = np.linspace(0, 65535, H * W).astype(np.uint16).reshape(H, W)
    path = tmp_path / "v16.png"
    Image.fromarray(values).save(path)
    vis = load_candidate(path, channel="visibility")
    np.testing.assert_allclose(vis, values / 65535.0, atol=1e-7)
    assert vis.max() == 1.0


def test_png_16bit_colour_keeps_16_bits(tmp_path):
    from raster_oracle.metrics.tonemap import srgb_decode

    rng = np.random.default_rng(4)
    values = rng.integers(0, 65536, (H, W, 3))
    values[0, 0] = [40000, 40001, 40002]  # differ only below 8 bits
    path = tmp_path / "c16.png"
    _write_png_raw(path, values, 16, 2)
    rgb = load_candidate(path)
    np.testing.assert_allclose(rgb, srgb_decode(values / 65535.0), atol=1e-6)
    assert len(set(rgb[0, 0].tolist())) == 3


def test_png_colour_as_visibility_needs_grey(tmp_path):
    values = np.zeros((H, W, 3), np.uint8)
    values[..., 0] = 255
    path = tmp_path / "red.png"
    Image.fromarray(values).save(path)
    with pytest.raises(CandidateError, match="colour PNG with unequal R, G, B"):
        load_candidate(path, channel="visibility")
    with pytest.raises(CandidateError, match="PNG, which has no named channels"):
        load_candidate(path, channel="Z")


# --------------------------------------------------------------------------- errors


def test_wrong_size(tmp_path):
    path = tmp_path / "c.exr"
    write_exr(path, {"Y": np.zeros((360, 640))})
    with pytest.raises(CandidateError, match=r"^candidate is 640x360, the reference is 960x540"):
        load_candidate(path, expected_shape=(540, 960))


def test_missing_channel_lists_available(tmp_path, rgb):
    path = tmp_path / "c.exr"
    write_exr(path, {"depth": rgb[..., 0], "normal.X": rgb[..., 1]})
    with pytest.raises(
        CandidateError, match=r"has no channel 'color'; channels: depth, normal\.X; layers: normal$"
    ):
        load_candidate(path)
    with pytest.raises(CandidateError, match="several grey channels for visibility; pick one"):
        load_candidate(path, channel="visibility")


def test_visibility_from_unequal_rgb_exr_is_an_error(tmp_path, rgb):
    # the layout's rule (what `score` reads): grey data stored as R, G, B must be equal
    path = tmp_path / "c.exr"
    write_exr(path, {c: rgb[..., i] for i, c in enumerate("RGB")})
    with pytest.raises(CandidateError, match="has unequal R, G, B: visibility needs one grey"):
        load_candidate(path, channel="visibility")


def test_nan_and_inf_are_counted(tmp_path, rgb):
    bad = rgb.copy()
    bad[0, 0, 0] = np.nan
    bad[1, 1, 1] = np.nan
    bad[2, 2, 2] = np.inf
    path = tmp_path / "c.exr"
    write_exr(path, {c: bad[..., i] for i, c in enumerate("RGB")})
    with pytest.raises(CandidateError, match="has 2 NaN and 1 inf values"):
        load_candidate(path)


def test_negative_radiance_and_visibility_range(tmp_path, rgb):
    neg = rgb.copy()
    neg[0, 0, 0] = -0.5
    path = tmp_path / "c.exr"
    write_exr(path, {c: neg[..., i] for i, c in enumerate("RGB")} | {"visibility": neg[..., 0]})
    with pytest.raises(
        CandidateError, match=r"radiance must be >= 0, got 1 negative values \(min -0.5\)"
    ):
        load_candidate(path)
    with pytest.raises(
        CandidateError, match=r"visibility must be in \[0, 1\], got 1 values outside \(min -0.5\)"
    ):
        load_candidate(path, channel="visibility")


@pytest.mark.parametrize("fraction", [0.5, 0.05])
def test_truncated_exr(tmp_path, rgb, fraction):
    path = tmp_path / "c.exr"
    write_exr(path, {c: rgb[..., i] for i, c in enumerate("RGB")})
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * fraction)])
    with pytest.raises(CandidateError, match="c.exr is truncated or not a readable EXR"):
        load_candidate(path)


def test_truncated_and_fake_png(tmp_path):
    values = np.random.default_rng(2).integers(0, 256, (64, 64, 3), dtype=np.uint8)
    path = tmp_path / "c.png"
    Image.fromarray(values).save(path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(CandidateError, match="c.png is truncated or not a readable PNG"):
        load_candidate(path)
    path.write_bytes(b"not a png at all, just text")
    with pytest.raises(CandidateError, match="c.png is truncated or not a PNG file"):
        load_candidate(path)


def test_unknown_extension_and_missing_file(tmp_path):
    path = tmp_path / "c.jpg"
    path.write_bytes(b"\xff\xd8")
    with pytest.raises(CandidateError, match="unknown candidate file extension '.jpg'"):
        load_candidate(path)
    with pytest.raises(CandidateError, match="candidate file not found"):
        load_candidate(tmp_path / "missing.exr")


def test_candidate_error_is_a_value_error():
    assert issubclass(CandidateError, ValueError)
