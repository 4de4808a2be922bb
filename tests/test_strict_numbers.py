"""Issue 48: one strict rule for numbers written as text (scene names, options, ``--set``),
and sizes bounded by an estimate before anything is allocated."""

from __future__ import annotations

import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.scenes.base import numbers
from raster_oracle.scenes.catalogue import builtin

from raster_oracle import raster_models

HUGE = "9" * 5000
BAD_INTS = ["1_", "1__0", "1_0", " 1", "+5", "0x10", "1e3", "٣", HUGE, ""]


@pytest.mark.parametrize("text", BAD_INTS)
def test_parse_int_refuses_what_python_int_might_take(text):
    with pytest.raises(numbers.NumberError) as info:
        numbers.parse_int(text, what="n")
    assert "\n" not in str(info.value) and len(str(info.value)) < 200


@pytest.mark.parametrize("text", ["1_0.5", "nan", "inf", "1e400", "--1", "1.2.3", HUGE])
def test_parse_float_refuses_non_decimal_and_non_finite_text(text):
    with pytest.raises(numbers.NumberError):
        numbers.parse_float(text, what="x")


def test_plain_decimals_parse_exactly():
    assert numbers.parse_int("000123", what="n", lo=0, hi=200) == 123
    assert numbers.parse_int("-7", what="n", signed=True) == -7
    assert numbers.parse_float("-1.5e-3", what="x") == -0.0015
    assert numbers.parse_float(".5", what="x") == 0.5
    with pytest.raises(numbers.NumberError, match=r"n must be in \[0, 200\], got 201"):
        numbers.parse_int("201", what="n", lo=0, hi=200)


@pytest.mark.parametrize("value", ["1_", "1__0", HUGE])
def test_scene_parameters_follow_the_rule(value):
    with pytest.raises(builtin.SceneParamError, match="decimal digits only"):
        builtin.builtin_scene(f"meadow:n={value}")


@pytest.mark.parametrize(
    "argv",
    [
        ["reference", "meadow:n=1_"],
        ["reference", "meadow:seed=1__0"],
        ["reference", "plate", "--spp", HUGE],
        ["reference", "plate", "--spp", "1_6"],
        ["reference", "plate", "--width", "1__6"],
        ["reference", "plate", "--target-stderr", "1_0.5"],
        ["reference", "plate", "--frames", "1000000"],
        ["model", "msaa", "plate", "--set", "samples=1_6"],
        ["model", "msaa", "plate", "--set", f"samples={HUGE}"],
    ],
)
def test_the_command_line_refuses_with_one_line(argv, tmp_path, capfd):
    out = tmp_path / "o"
    rc = main([*argv, "--quiet", "--no-cache", "--out", str(out)])
    err = capfd.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "Traceback" not in err[0], err
    assert len(err[0]) < 400
    assert not out.exists()


def test_set_still_takes_whole_floats():
    params = raster_models.parse_params("msaa", ["samples=4.0"])
    assert params["samples"] == 4
    with pytest.raises(raster_models.ModelError):
        raster_models.parse_params("msaa", ["samples=4_0"])


@pytest.mark.parametrize("scene", ["meadow:n=100000000", "city-foliage:n=100000000"])
def test_a_scene_larger_than_free_memory_is_refused_before_it_is_built(scene, monkeypatch):
    monkeypatch.setattr(builtin, "available_memory", lambda: 8 * 2**30)
    with pytest.raises(builtin.SceneParamError, match=r"needs about 55\.9 GiB .* 8\.0 GiB free"):
        builtin.builtin_scene(scene)
    assert builtin.builtin_scene(scene.replace("100000000", "1000")) is not None
