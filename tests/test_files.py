"""Writing files: large arrays go into an ``.npz`` a block of rows at a time, to the bytes
``numpy`` writes."""

import io
import zipfile

import numpy as np
import pytest

from azee_mj.files import ROWS_BYTES, Chain, save_npz


@pytest.mark.parametrize(
    "array",
    [
        np.arange(3 * ROWS_BYTES // 8 + 5, dtype=float).reshape(-1, 1) / 7.0,  # rows of 8 bytes
        np.random.default_rng(0).random((9_000, 120)),  # the postures of 3 minutes
        np.array([f"block {i}#0" for i in range(60_000)]),  # fixed-width text
        np.arange(10, dtype=np.int64),  # small: numpy writes it
    ],
)
def test_an_array_is_written_as_numpy_writes_it(tmp_path, array):
    save_npz(tmp_path / "a.npz", {"a": array})
    with zipfile.ZipFile(tmp_path / "a.npz") as z:
        written = z.read("a.npy")
    expected = io.BytesIO()
    np.lib.format.write_array(expected, array, allow_pickle=False)
    assert written == expected.getvalue()
    np.testing.assert_array_equal(np.load(tmp_path / "a.npz")["a"], array)


@pytest.mark.parametrize("parts", [[np.arange(5.0), np.zeros(0), np.ones(3)], []])
def test_a_chain_is_written_as_its_concatenation(tmp_path, parts):
    save_npz(tmp_path / "c.npz", {"c": Chain(parts, float)})
    whole = np.concatenate(parts) if parts else np.zeros(0)
    with zipfile.ZipFile(tmp_path / "c.npz") as z:
        written = z.read("c.npy")
    expected = io.BytesIO()
    np.lib.format.write_array(expected, whole, allow_pickle=False)
    assert written == expected.getvalue()
