"""Spec §6 data rules: each rejection names the row or channel; formats, units, sections."""
import math
import subprocess
import sys

import numpy as np
import pytest

from pumpsim.data import DataOptions, load_data, resample, speed_trend, steady_section
from pumpsim.errors import DataError
from tests.conftest import ROOT
from tests.tolerances import (MAD_SIGMA_SE, MAD_SIGMA_Z, ROUNDING_REL, RUNUP_TREND_REL, STEADY_EDGE_ABS,
                              WHOLE_REVOLUTION_SAMPLES)

W = 471.0
GOOD_T = np.arange(0, 0.03, 1e-4)


def write_csv(path, header, rows, comments=("# measured on the rig",)):
    lines = list(comments) + [header] + [",".join(str(v) for v in r) for r in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def good_rows():
    return [[t, 0.07 + 0.001 * math.sin(4 * W * t)] for t in GOOD_T]


def test_good_csv_with_comments(tmp_path):
    ds = load_data(write_csv(tmp_path / "d.csv", "time,torque", good_rows()), nominal_speed=W)
    assert ds.n == GOOD_T.size and ds.speed is None


@pytest.mark.parametrize("mutate,message", [
    (lambda r: r.__setitem__(5, [r[5][0], float("nan")]), "row 8: torque is not a finite number"),
    (lambda r: r.__setitem__(10, [r[8][0], r[10][1]]), "row 13: time must be strictly increasing"),
    (lambda r: r.__setitem__(3, [r[3][0], "abc"]), "row 6: 'abc' is not a number"),
    (lambda r: r.__setitem__(4, [r[4][0]]), "row 7: 1 values, the header has 2 columns"),
])
def test_bad_rows_are_named(tmp_path, mutate, message):
    """Rows are line numbers of the file (comment and header lines count), as an editor shows."""
    rows = good_rows()
    mutate(rows)
    with pytest.raises(DataError) as e:
        load_data(write_csv(tmp_path / "d.csv", "time,torque", rows), nominal_speed=W)
    assert message in str(e.value)


def test_missing_column_and_too_short(tmp_path):
    with pytest.raises(DataError, match="has no column 'torque' \\(found: time, tq\\)"):
        load_data(write_csv(tmp_path / "a.csv", "time,tq", good_rows()), nominal_speed=W)
    short = [r for r in good_rows() if r[0] < 0.005]
    with pytest.raises(DataError, match="too few samples for one revolution"):
        load_data(write_csv(tmp_path / "b.csv", "time,torque", short), nominal_speed=W)
    with pytest.raises(DataError, match="cannot read data"):
        load_data(tmp_path / "none.csv")


def test_units_and_column_mapping(tmp_path):
    rows = [[t, 1000 * tq, 5800.0] for t, tq in good_rows()]
    ds = load_data(write_csv(tmp_path / "d.csv", "t_s,Tq_Nmm,n_rpm", rows),
                   DataOptions(time="t_s", torque="Tq_Nmm", speed="n_rpm", torque_unit="N*mm", speed_unit="rpm"))
    np.testing.assert_allclose(ds.torque, [r[1] for r in good_rows()])
    np.testing.assert_allclose(ds.speed, 5800 * 2 * math.pi / 60)
    with pytest.raises(DataError, match="torque unit must be one of"):
        load_data(tmp_path / "d.csv", DataOptions(torque_unit="kgf"))


def test_mat_and_tdms_files(tmp_path):
    from nptdms import ChannelObject, TdmsWriter
    from scipy.io import savemat

    t = GOOD_T
    tq = np.array([r[1] for r in good_rows()])
    savemat(tmp_path / "d.mat", {"time": t, "torque": tq})
    ds = load_data(tmp_path / "d.mat", nominal_speed=W)
    np.testing.assert_allclose(ds.torque, tq)
    with TdmsWriter(str(tmp_path / "d.tdms")) as w:
        w.write_segment([ChannelObject("rig", "time", t), ChannelObject("rig", "Torque", tq)])
    ds = load_data(tmp_path / "d.tdms", DataOptions(torque="Torque"), nominal_speed=W)
    np.testing.assert_allclose(ds.torque, tq)
    ds = load_data(tmp_path / "d.tdms", nominal_speed=W)  # 'Torque' is the torque column (case)
    np.testing.assert_allclose(ds.torque, tq)
    with pytest.raises(DataError, match="has no channel 'Drehmoment'"):
        load_data(tmp_path / "d.tdms", DataOptions(torque="Drehmoment"), nominal_speed=W)
    bad = tq.copy()
    bad[7] = np.nan
    with TdmsWriter(str(tmp_path / "e.tdms")) as w:
        w.write_segment([ChannelObject("rig", "time", t), ChannelObject("rig", "torque", bad)])
    with pytest.raises(DataError, match="sample 7 of channel 'torque'"):
        load_data(tmp_path / "e.tdms", nominal_speed=W)


def test_steady_section_of_a_run_up_and_resampling():
    t = np.linspace(0, 1.0, 5001)
    w = np.minimum(t / 0.3, 1.0) * 600 + np.where(t > 0.8, (t - 0.8) * -2000, 0)
    from pumpsim.data import Dataset

    ds = steady_section(Dataset(t, np.ones_like(t), w), tolerance=0.01)
    assert ds.time[0] == pytest.approx(0.297, abs=STEADY_EDGE_ABS) and ds.time[-1] == pytest.approx(0.803, abs=STEADY_EDGE_ABS)
    r = resample(ds, 1000.0)
    assert np.allclose(np.diff(r.time), 1e-3)
    with pytest.raises(DataError, match="needs a speed column"):
        steady_section(Dataset(t, np.ones_like(t)))


def test_cli_identify_rejects_bad_data_with_status_2(tmp_path):
    rows = good_rows()
    rows[5][1] = float("nan")
    f = write_csv(tmp_path / "d.csv", "time,torque", rows)
    out = tmp_path / "fit.json"
    r = subprocess.run([sys.executable, "-m", "pumpsim", "identify", "examples/ellipse_4vanes.toml", str(f),
                        "--json", str(out)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2 and "row 8: torque is not a finite number" in r.stderr
    assert not out.exists() and "Traceback" not in r.stderr


def test_quoted_decimal_comma_fields_with_comma_separator(tmp_path):
    """A spreadsheet's CSV export in a German locale: ',' separates, values are quoted and use a
    decimal comma ("0,0701"); the header carries units. Read as the same numbers (it was refused:
    'row 3: 4 values, the header has 2 columns')."""
    rows = good_rows()
    p = tmp_path / "d.csv"
    p.write_text("# export\ntime [ms],torque [N*mm]\n" + "".join(
        f'"{t * 1e3:.6f}","{q * 1e3:.9f}"\n'.replace(".", ",") for t, q in rows))
    ds = load_data(p, nominal_speed=W)
    assert ds.n == len(rows)
    assert np.array_equal(ds.time, np.array([float(f"{t * 1e3:.6f}") for t, _ in rows]) * 1e-3)
    assert np.array_equal(ds.torque, np.array([float(f"{q * 1e3:.9f}") for _, q in rows]) * 1e-3)


def test_quoted_field_with_bad_number_names_the_row(tmp_path):
    p = tmp_path / "d.csv"
    p.write_text('time,torque\n"0,0","0,07"\n"0,0001","x,1"\n')
    with pytest.raises(DataError, match=r"row 3: 'x.1' is not a number"):
        load_data(p)


def test_speed_trend_follows_a_record_that_starts_mid_run_up():
    """A speed column whose record starts during the run-up (omega = w (1 - a (1 - t/T)^2) up to
    T = 21 % of the record, a = 0.14, then w; 97 revolutions): the trend the model follows must
    match it (independent artefact 'runup' on the concentric rig was `unexplained` at SNR 10)."""
    w, a = 607.37, 0.143
    t = np.arange(12500) / 12500.0
    x = np.clip(t / 0.2085, 0.0, 1.0)
    omega = w * (1 - a * (1 - x) ** 2)
    tr = speed_trend(t, omega)
    assert tr is not None
    assert np.max(np.abs(tr.speed(t) - omega)) / w < RUNUP_TREND_REL


def test_time_errors_show_enough_digits_and_say_when_times_repeat(tmp_path):
    """Absolute time stamps (1.7e9 s) going backwards are shown with the digits that tell them apart
    (were '1.7e+09 s after 1.7e+09 s'); times written with too few digits for the rate repeat, and
    the message says so."""
    p = tmp_path / "a.csv"
    p.write_text("time,torque\n1700000000.0001,0.1\n1700000000.0002,0.1\n1700000000.0001,0.1\n")
    with pytest.raises(DataError, match=r"row 4: .*\(1700000000\.0001 s after 1700000000\.0002 s\)"):
        load_data(p)
    p.write_text("time,torque\n" + "".join(f"{k * 5e-5:.4f},0.1\n" for k in range(20)))
    with pytest.raises(DataError, match=r"row \d+: .*repeated times: written with too few digits"):
        load_data(p)


def test_blank_separated_columns_with_units(tmp_path):
    """A logger's text export with columns separated by runs of blanks and units with a blank
    inside ('torque [N mm]'): read as the same numbers (was 'row 3: '0 70' is not a number')."""
    rows = good_rows()
    p = tmp_path / "d.txt"
    p.write_text("# export\ntime [ms]   torque [N mm]\n" + "".join(f"{t * 1e3:10.4f}  {q * 1e3:.6f}\n" for t, q in rows))
    ds = load_data(p, nominal_speed=W)
    assert ds.n == len(rows)
    assert np.array_equal(ds.torque, np.array([float(f"{q * 1e3:.6f}") for _, q in rows]) * 1e-3)


@pytest.mark.parametrize("k, phase", [(3, -1.0), (1, -math.pi / 2), (6, -2.5)])
def test_mean_speed_of_a_rippled_column_is_the_mean_over_whole_revolutions(k, phase):
    """omega = W (1 + eps cos(k W t + phase)) over about 1 s, ending a quarter ripple period past a
    whole one (a part revolution at the end): the plain mean carries eps W (sin(k W T + phase) - sin(phase)) / (k W T) of the unfinished ripple period;
    the mean over whole revolutions misses at most one sample's share of the ripple."""
    from pumpsim.data import Dataset
    eps, rate = 0.028, 20000.0
    m = round(k * W / (2 * math.pi))
    t = np.arange(0, (2 * math.pi * m + math.pi / 2 - phase) / (k * W), 1 / rate)
    w = W * (1 + eps * np.cos(k * W * t + phase))
    ds = Dataset(t, np.zeros_like(t), speed=w)
    bound = WHOLE_REVOLUTION_SAMPLES * eps * W / (rate * t[-1])
    assert abs(ds.mean_speed() - W) <= bound
    plain = eps * W * (math.sin(k * W * t[-1] + phase) - math.sin(phase)) / (k * W * t[-1])
    assert abs(np.mean(w) - W - plain) <= bound  # the closed form of the plain mean's bias
    assert abs(plain) > 5 * bound  # so the test can tell them apart
    short = Dataset(t[:50], np.zeros(50), speed=w[:50])  # less than one revolution: the plain mean
    assert short.mean_speed() == pytest.approx(float(np.mean(w[:50])), rel=ROUNDING_REL)


def test_third_difference_noise_reads_white_noise_and_not_a_ripple():
    """Third differences: the sigma of white noise within its sampling error, a 2.8 % order-3 ripple of an exact column at 20 kHz as
    (2 pi k w / rate)^3 of its size, far below any logger's noise."""
    from pumpsim.signals import noise_sigma
    n, rate = 20000, 20000.0
    t = np.arange(n) / rate
    noise = 1.5 * np.random.default_rng(3).standard_normal(n)
    assert abs(noise_sigma(W + noise, order=3) / 1.5 - 1) < MAD_SIGMA_Z * MAD_SIGMA_SE / math.sqrt(n)
    ripple = W * 0.028 * np.cos(3 * W * t)
    assert noise_sigma(W + ripple, order=3) < 1.1 * 0.028 * W * (3 * W / rate) ** 3


def test_a_line_of_units_under_the_header(tmp_path):
    """Loggers often write the units on a line of their own under the names: they are the columns'
    units (said in the notes), and row numbers in messages still count that line."""
    rows = [[1e3 * t, 1e3 * tq] for t, tq in good_rows()]
    ds = load_data(write_csv(tmp_path / "u.csv", "time,torque\nms,[N*mm]", rows), nominal_speed=W)
    np.testing.assert_allclose(ds.torque, [r[1] for r in good_rows()])
    assert ds.time[1] == pytest.approx(1e-4) and any("units from row 3" in n for n in ds.notes)
    rows[4][1] = "x"
    with pytest.raises(DataError, match="row 8: 'x' is not a number"):
        load_data(write_csv(tmp_path / "v.csv", "time,torque\nms,N*mm", rows), nominal_speed=W)


def test_time_stamps_in_the_time_column(tmp_path):
    """ISO 8601 time stamps (a blank or 'T', fractions, a zone) are seconds after the first, to the
    microsecond; a stamp that does not parse is a bad row."""
    from datetime import datetime, timedelta

    t0 = datetime(2026, 11, 27, 23, 59, 59, 990000)
    rows = [[(t0 + timedelta(microseconds=round(1e6 * t))).isoformat(sep=" ") + "+01:00", tq]
            for t, tq in good_rows()]
    ds = load_data(write_csv(tmp_path / "s.csv", "time,torque", rows), nominal_speed=W)
    np.testing.assert_allclose(ds.time, GOOD_T, rtol=0, atol=1e-9)
    assert any("time stamps" in n and "2026-11-27 23:59:59.990000" in n for n in ds.notes)
    rows[6][0] = "2026-11-28 25:00:00"
    with pytest.raises(DataError, match="row 9: '2026-11-28 25:00:00' is not a number"):
        load_data(write_csv(tmp_path / "b.csv", "time,torque", rows), nominal_speed=W)


def test_parquet_files(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    t = GOOD_T
    tq = np.array([r[1] for r in good_rows()])
    pq.write_table(pa.table({"time": t, "torque [N*mm]": 1000 * tq, "comment": ["x"] * t.size}),
                   tmp_path / "d.parquet")
    ds = load_data(tmp_path / "d.parquet", nominal_speed=W)
    np.testing.assert_allclose(ds.torque, tq)
    stamps = (np.datetime64("2026-11-28T10:00:00", "ns") + (t * 1e9).astype("timedelta64[ns]"))
    pq.write_table(pa.table({"timestamp": pa.array(stamps), "torque": tq}), tmp_path / "s.parquet")
    ds = load_data(tmp_path / "s.parquet", DataOptions(time="timestamp"), nominal_speed=W)
    np.testing.assert_allclose(ds.time - ds.time[0], t - t[0], atol=1e-9)
    (tmp_path / "p.csv").write_bytes((tmp_path / "d.parquet").read_bytes())
    with pytest.raises(DataError, match="Apache Parquet file; name it .parquet"):
        load_data(tmp_path / "p.csv", nominal_speed=W)
