"""The Dask route of docs/python.md: a per-pixel fit in bands of rows on Dask's threads equals
the whole field's fit, byte for byte."""

import numpy as np
import pytest

import lightstage as ls

dask = pytest.importorskip("dask")


def test_fit_in_bands_with_dask(field_file, tmp_path):
    f = ls.Field.open(field_file)
    rows = 16

    def fit_band(y0):
        band = tmp_path / f"band_{y0:05d}.exr"
        f.save_rows(band, y0, min(y0 + rows, f.height), storage="float")
        return ls.fit(band, materials="per-pixel").maps

    bands = dask.compute(*[dask.delayed(fit_band)(y0) for y0 in range(0, f.height, rows)],
                         scheduler="threads", num_workers=2)
    assert [b["model"].shape[0] for b in bands] == [16, 16, 8]
    tiled = {name: np.concatenate([b[name] for b in bands]) for name in bands[0]}
    whole = ls.fit(field_file, materials="per-pixel").maps
    assert tiled.keys() == whole.keys()
    for name, array in whole.items():
        assert tiled[name].tobytes() == np.ascontiguousarray(array).tobytes(), name
