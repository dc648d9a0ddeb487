"""lightstage.Field: the header, rows and the whole field as arrays over the library's memory."""

import json

import numpy as np
import pytest

import lightstage as ls
from conftest import RESOLUTION, ROOT


def test_header(field, stage_file):
    stage = json.loads(stage_file.read_text())
    leds = stage["leds"]
    assert field.shape == (RESOLUTION, RESOLUTION, len(leds), 3)
    assert (field.height, field.width) == (RESOLUTION, RESOLUTION)
    lights = field.lights
    assert len(lights) == len(leds)
    assert list(lights.ids) == [led["id"] for led in leds]
    # The directions are the stage file's, normalised.
    expected = np.array([led["direction"] for led in leds], dtype=np.float64)
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    np.testing.assert_allclose(lights.directions, expected, atol=1e-6)
    assert lights.valid.all()
    assert np.isnan(lights.positions).all()  # The built-in dome's LEDs are distant.
    assert lights.saturates_at.shape == (len(leds), 3)
    # Stored per unit of each LED's calibrated colour: white lights.
    np.testing.assert_array_equal(lights.colours, np.ones((len(leds), 3)))
    # A simulated capture measures its noise: both terms positive.
    noise = field.noise
    assert noise.measured
    assert noise.read_variance > 0 and noise.shot_variance_per_unit > 0
    assert field.storage in ("half", "float")


def test_rows_are_the_fields_rows(field):
    whole = field.values()
    assert whole.dtype == np.float32 and whole.shape == field.shape
    assert whole.flags.c_contiguous
    band = field.rows(5, 12)
    assert band.shape == (7,) + field.shape[1:]
    assert band.tobytes() == whole[5:12].tobytes()
    assert field.rows(0, field.height).tobytes() == whole.tobytes()
    # Physical bound: radiance is not negative beyond the noise (5 sigma of the read noise).
    assert whole.min() > -5 * np.sqrt(field.noise.read_variance)
    assert whole.max() > 0


def test_rows_outside_the_field_are_refused(field):
    with pytest.raises(ls.InputError) as error:
        field.rows(3, field.height + 1)
    assert isinstance(error.value, ValueError)
    assert error.value.file == str(field.path)
    assert error.value.field == "rows"
    assert "expected 0 <= y0 < y1 <= 40" in str(error.value)


def test_arrays_view_the_librarys_memory(field, tmp_path):
    a = field.values()
    b = field.values()
    # No copy: both are views of one buffer of the library's, their base.
    assert isinstance(a.base, ls.Buffer) and a.base.writable and a.flags.writeable
    assert np.shares_memory(a, b)
    band = field.rows(0, 2)
    assert isinstance(band.base, ls.Buffer) and not np.shares_memory(band, a)
    original = field.rows(0, field.height)
    # Written through the array, seen by the library: save() writes what the array now holds.
    a[3, 4, 7, :] = [1.5, 2.5, 3.5]
    a[0] *= 2
    field.save(tmp_path / "edited.exr", storage="float")
    edited = ls.Field.open(tmp_path / "edited.exr").values()
    np.testing.assert_array_equal(edited[3, 4, 7], [1.5, 2.5, 3.5])
    np.testing.assert_array_equal(edited[0], 2 * original[0])
    np.testing.assert_array_equal(edited[1:3], original[1:3])


def test_derived_views_keep_the_buffer(field):
    # Arrays NumPy derives from a view keep the library's buffer as their root base.
    view = field.values()[::2]
    assert isinstance(view.base.base, ls.Buffer)
    image, names = ls.read_image(field.path)
    assert isinstance(image.base, ls.Buffer)
    assert image.shape[2] == len(names)


def test_missing_file(tmp_path):
    missing = tmp_path / "missing.exr"
    with pytest.raises(ls.InputError) as error:
        ls.Field.open(missing)
    assert error.value.file == str(missing)


def test_save_rows(field, tmp_path):
    field.save_rows(tmp_path / "band.exr", 8, 20, storage="float")
    band = ls.Field.open(tmp_path / "band.exr")
    assert band.shape == (12,) + field.shape[1:]
    assert band.values().tobytes() == field.rows(8, 20).tobytes()
    np.testing.assert_array_equal(band.lights.directions, field.lights.directions)
    assert band.noise.read_variance == field.noise.read_variance


def test_save_rows_refuses_near_leds(tmp_path):
    # The hand-written small dome has two near LEDs (positions, not directions).
    stage = json.loads(
        "\n".join(line for line in (ROOT / "data" / "stages" / "small_dome.json").read_text()
                  .splitlines() if not line.strip().startswith("//")))
    stage["camera"]["width"] = stage["camera"]["height"] = 16
    (tmp_path / "stage.json").write_text(json.dumps(stage))
    ls.capture(tmp_path / "stage.json", out=tmp_path / "s")
    near = ls.build(tmp_path / "s", out=tmp_path / "near.exr").fields[0]
    assert np.isfinite(near.lights.positions).any(axis=1).sum() == 2
    with pytest.raises(ls.InputError) as error:
        near.save_rows(tmp_path / "band.exr", 0, 8)
    assert "near LEDs" in error.value.message and error.value.field == "save_rows"
