"""A receiver that stamps packets in bursts repeats its time: allowed, only going back is not."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imucal import io
from imucal.columns import SEQ, TIME
from imucal.ingest import check_log


def test_packets_of_one_burst_may_share_a_receiver_time():
    """Ten packets per 0.1 s burst, all stamped with the burst's arrival time: non-decreasing,
    so accepted; the same log with one stamp a step back is refused at that line."""
    n = 100
    t_s = np.repeat(np.arange(n // 10) * 0.1, 10)
    table = pd.DataFrame({TIME: t_s, SEQ: np.arange(n)})
    check_log(table, "bursts.csv", first_line=2)
    back = table.copy()
    back.loc[55, TIME] = 0.4
    with pytest.raises(io.RawDataError, match=r"line 57: t_s 0.4 s is earlier than 0.5 s"):
        check_log(back, "bursts.csv", first_line=2)
