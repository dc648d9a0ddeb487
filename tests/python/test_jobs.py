"""The jobs from Python equal the command line's: the same files byte for byte, and arrays that
hold exactly what those files hold."""

import filecmp
import shutil

import numpy as np
import pytest

import lightstage as ls
from conftest import ENVMAP


def same_files(a, b):
    """Every file of folder a is in folder b with the same bytes (and no other)."""
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir())
    match, mismatch, errors = filecmp.cmpfiles(a, b, names, shallow=False)
    assert mismatch == [] and errors == [], (mismatch, errors)
    return names


def file_channels(path):
    """An EXR's channels by name, as the library reads the file."""
    image, names = ls.read_image(path)
    return {name: image[..., c] for c, name in enumerate(names)}


def test_relight_equals_the_cli(cli, field_file, tmp_path):
    out = tmp_path / "relit"
    cli("relight", field_file, "--env", ENVMAP, "--rotate", 0, 90, "--out", out, "--quiet")
    reference = tmp_path / "relit_cli"
    shutil.move(out, reference)
    relit = ls.relight(ls.Field.open(field_file), env=ENVMAP, rotate=[0, 90], out=out)
    names = same_files(out, reference)
    assert "contact_sheet.png" in names
    assert len(relit.images) == 2
    for label, image in relit.images.items():
        assert image.dtype == np.float32 and image.shape == (40, 40, 3)
        expected, channels = ls.read_image(reference / f"{label}.exr")
        assert channels == ["R", "G", "B"]
        assert image.tobytes() == expected.tobytes()
    # Without out: the same images, from files that are gone.
    again = ls.relight(field_file, env=[ENVMAP], rotate=np.array([0, 90]))
    assert again.out is None
    for label, image in again.images.items():
        assert image.tobytes() == relit[label].tobytes()


def test_fit_equals_the_cli(cli, field_file, tmp_path):
    out = tmp_path / "maps.exr"
    cli("fit", field_file, "--out", out, "--quiet")
    reference = tmp_path / "cli"
    reference.mkdir()
    for p in tmp_path.glob("maps*"):
        shutil.move(p, reference / p.name)
    fitted = ls.fit(field_file, out=out)
    produced = tmp_path / "py"
    produced.mkdir()
    for p in tmp_path.glob("maps*"):
        shutil.move(p, produced / p.name)
    same_files(produced, reference)
    channels = file_channels(reference / "maps.exr")
    maps = fitted.maps
    for stem, parts in (("normal", "xyz"), ("albedo", "rgb")):
        assert maps[stem].shape == (40, 40, 3)
        for k, part in enumerate(parts):
            assert maps[stem][..., k].tobytes() == channels[f"{stem}.{part}"].tobytes()
    for name in ("sigma", "ks", "roughness", "model", "confidence", "residual", "flags",
                 "material", "material_weight", "material2", "material2_weight"):
        assert maps[name].tobytes() == channels[name.replace("_", ".")].tobytes(), name
    # The arrays view the library's maps; model codes are FitModel's 0..4.
    assert isinstance(maps["model"].base, ls.Buffer)
    assert set(np.unique(maps["model"])) <= {0, 1, 2, 3, 4}
    s = fitted.summary
    assert s["fitted"] + s["flagged"] + s["empty"] == 40 * 40
    # Where the time went, each part measured and within the whole (the noise is chosen and the
    # bands read outside it).
    times = s["times"]
    assert set(times) == {"noise", "normals", "candidates", "materials", "shadows", "writing",
                          "reading"}
    assert times["candidates"] > 0
    within = sum(v for k, v in times.items() if k not in ("noise", "reading"))
    assert within <= s["seconds"] + 0.05
    # Physics: unit normals where fitted, albedo within [0, 1].
    fit = maps["model"] > 0
    np.testing.assert_allclose(np.linalg.norm(maps["normal"][fit], axis=1), 1, atol=1e-4)
    assert maps["albedo"][fit].min() >= 0 and maps["albedo"][fit].max() <= 1


def test_build_equals_the_cli(cli, session_dir, tmp_path):
    out = tmp_path / "field.exr"
    cli("build", session_dir, "--out", out, "--quiet")
    reference = tmp_path / "cli.exr"
    shutil.move(out, reference)
    built = ls.build(session_dir, out=out)
    assert filecmp.cmp(out, reference, shallow=False)
    (field,) = built.fields
    assert isinstance(field, ls.Field) and field.shape == ls.Field.open(reference).shape
    assert built.summary["fields"][0]["lights"] == field.shape[2]


def test_capture_then_build(stage_file, tmp_path):
    captured = ls.capture(stage_file, out=tmp_path / "s", seed=3)
    assert captured.summary["frames_captured"] > 0
    assert not captured.summary["already_complete"]
    again = ls.capture(out=tmp_path / "s", resume=True)
    assert again.summary["already_complete"]
    built = ls.build(tmp_path / "s", out=tmp_path / "f.exr")
    assert built.fields[0].shape[:2] == (40, 40)


def test_normals(field_file):
    result = ls.normals(field_file)
    n = result.maps["normal"]
    assert n.shape == (40, 40, 3)
    ok = result.maps["flags"] == 0
    assert ok.sum() > 0
    np.testing.assert_allclose(np.linalg.norm(n[ok], axis=1), 1, atol=1e-4)
    # Seen by the camera (on +Z): normals face it.
    assert (n[ok][:, 2] > -1e-6).all()


def test_compress_and_render(field_file, tmp_path):
    pca = ls.compress(field_file, out=tmp_path / "f.pca", format="pca", rank="auto")
    assert pca.summary["representation"].startswith("pca")
    rendered = ls.render(tmp_path / "f.pca", light=[0, 1, 1])
    assert rendered.image.shape == (40, 40, 3) and rendered.out is None
    # Relit under an LED's own direction, the PCA gives back that LED's image of the field, within
    # the noise floor its rank was chosen from (a 1% relative error is many sigmas of it).
    field = ls.Field.open(field_file)
    dirs = field.lights.directions
    l = int(np.argmax(dirs[:, 2]))  # The LED nearest the camera: a well-lit image.
    rendered = ls.render(tmp_path / "f.pca", light=dirs[l], out=tmp_path / "led.exr")
    assert (tmp_path / "led.exr").exists() and (tmp_path / "led.png").exists()
    led = field.values()[:, :, l, :]
    error = np.sqrt(np.mean((rendered.image - led) ** 2)) / np.sqrt(np.mean(led ** 2))
    assert error < 0.01


def test_compress_refuses_a_bad_format(field_file, tmp_path, cli):
    with pytest.raises(ls.InputError) as error:
        ls.compress(field_file, out=tmp_path / "f.x", format="jpeg")
    result = cli("compress", field_file, "--out", tmp_path / "f.x", "--format", "jpeg", check=False)
    assert result.returncode == 2
    assert error.value.message in result.stderr
