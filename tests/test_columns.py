"""Column values of a table: the same array as pandas's selection of several columns."""

from __future__ import annotations

import numpy as np
import pandas as pd

from imucal.columns import ACC, SEQ, TIME, column_values


def _table() -> pd.DataFrame:
    rng = np.random.default_rng(3)
    n = 50
    acc = rng.normal(size=(n, 3))
    acc[[4, 9], 1] = np.nan  # rows of another stream
    table = pd.DataFrame({TIME: np.arange(n) / 100.0, SEQ: np.arange(n, dtype=np.int64)})
    for i, c in enumerate(ACC):
        table[c] = acc[:, i]
    return table


def test_column_values_are_pandas_selection_in_its_memory_order() -> None:
    table = _table()
    for columns, rows in ((ACC, slice(None)), (ACC, slice(3, 17)), ((TIME, SEQ), slice(40, 50))):
        expected = table.iloc[rows][list(columns)].to_numpy(dtype=float)
        got = column_values(table, columns, rows)
        # copied data, not fitted values: equal bit for bit (NaN where pandas has NaN)
        np.testing.assert_array_equal(got, expected)
        assert got.dtype == expected.dtype and got.strides == expected.strides
        assert got.flags.writeable


def test_column_values_of_no_rows_keep_the_columns() -> None:
    assert column_values(_table(), ACC, slice(5, 5)).shape == (0, 3)
