"""Errors: the library's messages as Python exceptions naming the file and field, the CLI's
validation messages."""

import pytest

import lightstage as ls
from conftest import ENVMAP


def test_option_errors_are_the_clis(cli, field_file, tmp_path):
    with pytest.raises(ls.InputError) as error:
        ls.fit(field_file, out=tmp_path / "maps.png")
    e = error.value
    assert isinstance(e, ValueError) and isinstance(e, ls.Error)
    assert e.field == "--out"
    assert "give a path ending in .exr" in e.message
    result = cli("fit", field_file, "--out", tmp_path / "maps.png", check=False)
    assert result.returncode == 1  # The CLI reports a bad option as a usage error.
    assert e.message.removeprefix("fit: ") in result.stderr

    with pytest.raises(ls.InputError) as error:
        ls.relight(field_file, out=tmp_path / "r")
    assert error.value.field == "--env"
    result = cli("relight", field_file, "--out", tmp_path / "r", check=False)
    assert error.value.message.removeprefix("relight: ") in result.stderr

    with pytest.raises(ls.InputError) as error:
        ls.relight(field_file, env=ENVMAP, memory="12 parsecs")
    assert error.value.field == "--memory"
    assert not (tmp_path / "r").exists()


def test_input_errors_name_the_file(tmp_path, cli):
    bad = tmp_path / "not_a_field.exr"
    bad.write_bytes(b"this is not an OpenEXR file")
    with pytest.raises(ls.InputError) as error:
        ls.fit(bad)
    assert error.value.file == str(bad)
    result = cli("fit", bad, "--out", tmp_path / "m.exr", check=False)
    assert result.returncode == 2
    assert error.value.message in result.stderr


def test_storage_errors_are_oserrors(field_file, tmp_path):
    # sysfs refuses new folders even to root: a storage fault (an output under a file is bad
    # input instead).
    unwritable = "/sys/kernel/lightstage-relit"
    with pytest.raises(ls.StorageError) as error:
        ls.relight(field_file, env=ENVMAP, out=unwritable)
    assert isinstance(error.value, OSError)
    assert unwritable in error.value.file
