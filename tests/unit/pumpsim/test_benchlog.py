"""Bench logs (spec §10): recognised by their columns, units from the headers, gauge pressure and
bad rows refused with the row, the column and the fix."""
import numpy as np
import pytest

from pumpsim.benchlog import fit_percent, is_bench_log, read_bench_log, unit_of
from pumpsim.config import load_config
from pumpsim.data import DataOptions
from pumpsim.errors import DataError
from tests.conftest import EXAMPLES

CFG = load_config(EXAMPLES / "evp_booster.toml")


def _write(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join(f"{v:.9g}" for v in r) for r in rows) + "\n")
    return path


def _rows(n=50, p0=101.3, unit_scale=1.0):
    t = np.arange(n) / 1000.0
    return [(ti, 13.5, 10.0 + ti, (p0 - 20 * ti) * unit_scale) for ti in t]


def test_reads_units_and_recognises_a_bench_log(tmp_path):
    f = _write(tmp_path / "log.csv", "time [ms],voltage [V],current [mA],booster_pressure [mbar abs]",
               [(1e3 * t, v, 1e3 * i, 10 * p) for t, v, i, p in _rows()])
    assert is_bench_log(f)
    log = read_bench_log(f, CFG)
    assert log.n == 50 and log.step == pytest.approx(1e-3)
    assert log.current[0] == pytest.approx(10.0) and log.booster_pressure[0] == pytest.approx(101300.0)
    assert log.start_pressure() == pytest.approx(101300.0, rel=1e-9)  # the quadratic holds a line exactly
    torque = _write(tmp_path / "torque.csv", "time,torque,voltage,current", [(0, 1, 2, 3), (1, 1, 2, 3)])
    assert not is_bench_log(torque)  # a torque measurement that logs the supply stays torque data


@pytest.mark.parametrize("unit,factor,kind", [("kPa", 1e3, None), ("bara", 1e5, "absolute"),
                                              ("kPa(a)", 1e3, "absolute"), ("kPa g", 1e3, "gauge"),
                                              ("psig", 6894.757293168, "gauge"), ("Pa", 1.0, None),
                                              ("mbar abs", 100.0, "absolute")])
def test_pressure_units_with_their_marks(unit, factor, kind):
    f, k = unit_of("booster_pressure", unit, "")
    assert f == pytest.approx(factor) and k == kind


def test_gauge_pressure_is_refused_with_the_fix(tmp_path):
    # a gauge pump-down from atmosphere: 0 kPa falling negative
    f = _write(tmp_path / "gauge.csv", "time,voltage,current,booster_pressure [kPa]", _rows(p0=0.0))
    with pytest.raises(DataError, match=r"row 2: booster_pressure 0 Pa is not positive: a gauge pressure\?.*add the atmospheric "
                                        r"pressure \(101\.325 kPa"):
        read_bench_log(f, CFG)
    marked = _write(tmp_path / "marked.csv", "time,voltage,current,booster_pressure [kPa g]", _rows(p0=5.0))
    with pytest.raises(DataError, match="marked gauge.*mark it absolute"):
        read_bench_log(marked, CFG)
    # positive but far below the atmosphere the config's pump-down starts from (bar gauge + offset)
    low = _write(tmp_path / "low.csv", "time,voltage,current,booster_pressure [kPa]", _rows(p0=20.0))
    with pytest.raises(DataError, match="starts at 2.* Pa, far below .*a gauge pressure"):
        read_bench_log(low, CFG)
    # the same column marked absolute is the user's word for it
    ok = _write(tmp_path / "abs.csv", "time,voltage,current,booster_pressure [kPa abs]", _rows(p0=20.0))
    assert read_bench_log(ok, CFG).booster_pressure[0] == pytest.approx(20e3)


def test_bad_rows_are_named(tmp_path):
    rows = _rows()
    rows[7] = (rows[7][0], float("nan"), rows[7][2], rows[7][3])
    f = _write(tmp_path / "nan.csv", "time,voltage,current,booster_pressure [kPa]", rows)
    with pytest.raises(DataError, match=r"row 9: voltage is not a finite number"):
        read_bench_log(f, CFG)
    rows = _rows()
    rows[10] = (rows[9][0], *rows[10][1:])
    f = _write(tmp_path / "mono.csv", "time,voltage,current,booster_pressure [kPa]", rows)
    with pytest.raises(DataError, match=r"row 12: time must be strictly increasing"):
        read_bench_log(f, CFG)
    rows = _rows()
    del rows[20:23]
    f = _write(tmp_path / "gap.csv", "time,voltage,current,booster_pressure [kPa]", rows)
    with pytest.raises(DataError, match=r"row 22: a gap of 0.004 s .*cut the log at the gap"):
        read_bench_log(f, CFG)
    f = _write(tmp_path / "part.csv", "time,voltage,current", [(t, v, i) for t, v, i, _ in _rows()])
    with pytest.raises(DataError, match=r"not a complete bench log: no column 'booster_pressure'"):
        read_bench_log(f, CFG)
    f = _write(tmp_path / "mv.csv", "time,voltage,current,booster_pressure [kPa]",
               [(t, 1e3 * v, i, p) for t, v, i, p in _rows()])
    with pytest.raises(DataError, match=r"median supply voltage 13500 V .*unit mistake"):
        read_bench_log(f, CFG)
    f = _write(tmp_path / "unit.csv", "time,voltage,current,booster_pressure [atm]", _rows())
    with pytest.raises(DataError, match=r"booster_pressure unit must be one of Pa, hPa, kPa"):
        read_bench_log(f, CFG)


def test_fit_percent_is_the_nrmse_fit():
    y = np.array([1.0, 2.0, 3.0, 4.0])
    assert fit_percent(y, y) == 100.0
    assert fit_percent(y, np.full(4, y.mean())) == pytest.approx(0.0)
    assert fit_percent(y, y + np.array([0.1, -0.1, 0.1, -0.1])) == pytest.approx(100 * (1 - 0.2 / np.sqrt(5)))


def test_a_log_starting_above_the_atmosphere_is_named(tmp_path):
    """A booster is evacuated from the atmosphere at most: a start 2 % above the config's
    gas.atmosphere (a sensor span error, or the day's barometer) is said; 0.2 % is not (inside the
    margin), nor a start below it."""
    from pumpsim.benchlog import BenchLog, start_above_atmosphere

    cfg = load_config(EXAMPLES / "evp_booster.toml")
    atm = cfg.pneumatic.values["gas.atmosphere"]
    t = np.arange(200) * 1e-3
    rng = np.random.default_rng(0)

    def log(scale):
        p = scale * (atm - 4e4 * (1 - np.exp(-t / 0.3))) + 50.0 * rng.standard_normal(t.size)
        return BenchLog(t, np.full_like(t, 13.5), np.full_like(t, 10.0), p, None, source="", notes=[])

    note = start_above_atmosphere(log(1.02), cfg)
    assert note is not None and "2 % above" in note and "gas.atmosphere" in note and "span" in note
    assert start_above_atmosphere(log(1.002), cfg) is None
    assert start_above_atmosphere(log(0.97), cfg) is None


@pytest.mark.parametrize("header,delim", [
    ("Time (s),Supply Voltage (V),Motor Current (A),Booster Pressure (kPa abs)", ","),
    ("t [ms];U [V];I [A];p [mbar abs]", ";"),
    ("TIME [s]\tU_bat [V]\tI_mot [A]\tP_Booster [kPa]", "\t")])
def test_logger_names_of_the_channels_are_recognised(tmp_path, header, delim):
    """A logger's own names for the channels (case, spaces, a unit in brackets, the usual short
    names U, I, p) read as the bench log's columns, each converted by its header's unit."""
    scale = [1e3 if "ms" in header else 1.0, 1.0, 1.0, 10.0 if "mbar" in header else 1.0]
    rows = [[v * k for v, k in zip(r, scale)] for r in _rows()]
    text = "\n".join(delim.join(f"{v:.9g}".replace(".", "," if delim == ";" else ".") for v in r) for r in rows)
    f = tmp_path / "logger.csv"
    f.write_text(header + "\n" + text + "\n")
    assert is_bench_log(f)
    log = read_bench_log(f, CFG)
    assert log.step == pytest.approx(1e-3) and log.voltage[0] == pytest.approx(13.5)
    assert log.current[3] == pytest.approx(10.003) and log.booster_pressure[0] == pytest.approx(101300.0)


def test_columns_and_units_named_by_options(tmp_path):
    """Names no alias covers, or two columns answering one alias, are given by DataOptions; a unit
    option that contradicts the header is refused naming both."""
    f = _write(tmp_path / "own.csv", "ts,Ub,Im,Pb", _rows())
    assert not is_bench_log(f)
    opts = DataOptions(time="ts", voltage="Ub", current="Im", booster_pressure="Pb", pressure_unit="kPa abs")
    assert is_bench_log(f, opts)
    assert read_bench_log(f, CFG, opts).booster_pressure[0] == pytest.approx(101300.0)
    two = _write(tmp_path / "two.csv", "time,voltage,current,p,pressure",
                 [(t, v, i, p, p) for t, v, i, p in _rows(unit_scale=1e3)])
    with pytest.raises(DataError, match=r"no column 'booster_pressure'.*--pressure-column"):
        read_bench_log(two, CFG)
    assert read_bench_log(two, CFG, DataOptions(booster_pressure="p")).booster_pressure[0] == pytest.approx(101300.0)
    marked = _write(tmp_path / "marked.csv", "time,voltage,current,booster_pressure [kPa]", _rows())
    with pytest.raises(DataError, match=r"annotated \[kPa\] but the pressure_unit option says 'mbar'.*drop one"):
        read_bench_log(marked, CFG, DataOptions(pressure_unit="mbar"))
    assert read_bench_log(marked, CFG, DataOptions(pressure_unit="kPa abs")).booster_pressure[0] == 101300.0


@pytest.mark.parametrize("channel,sign", [("current", -1.0), ("voltage", -1.0)])
def test_a_reversed_probe_is_refused(tmp_path, channel, sign):
    """A clamp or probe the wrong way round (the channel negative over most of the log) is bad input
    with the fix, not a fit that fails 100 noise sigmas off."""
    k = {"voltage": 1, "current": 2}[channel]
    rows = [tuple(sign * v if j == k else v for j, v in enumerate(r)) for r in _rows()]
    f = _write(tmp_path / "rev.csv", "time,voltage,current,booster_pressure [kPa]", rows)
    with pytest.raises(DataError, match=rf"'{channel}': the {channel} is negative over most of the log.*reverse"):
        read_bench_log(f, CFG)


@pytest.mark.parametrize("scale,unit", [(1e-3, "kPa"), (1e-2, "mbar"), (1e-5, "bar")])
def test_a_pressure_written_in_another_unit_is_named(tmp_path, scale, unit):
    """An unmarked pressure column whose start reads as the atmosphere in a bench's usual unit is
    refused naming that unit and how to say it, not as a gauge pressure."""
    f = _write(tmp_path / "p.csv", "time,voltage,current,booster_pressure",
               [(t, v, i, p * 1e3 * scale) for t, v, i, p in _rows()])
    with pytest.raises(DataError,
                       match=rf"as if written in {unit}: .*'booster_pressure \[{unit} abs\]'.*--pressure-unit"):
        read_bench_log(f, CFG)


def test_a_parquet_bench_log_reads_as_its_csv(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    rows = np.array([(1e3 * t, v, 1e3 * i, 10 * p) for t, v, i, p in _rows()])
    names = ["time [ms]", "voltage [V]", "current [mA]", "booster_pressure [mbar abs]"]
    csv = _write(tmp_path / "log.csv", ",".join(names), rows)
    pq.write_table(pa.table({n: rows[:, k] for k, n in enumerate(names)}), tmp_path / "log.parquet")
    assert is_bench_log(tmp_path / "log.parquet")
    a, b = read_bench_log(csv, CFG), read_bench_log(tmp_path / "log.parquet", CFG)
    for channel in ("time", "voltage", "current", "booster_pressure"):
        np.testing.assert_allclose(getattr(b, channel), getattr(a, channel), rtol=1e-8)


def test_the_motor_off_before_the_switch_on_and_after_the_switch_off_is_left_out(tmp_path):
    """The model starts the pump at rest, switched on, at the log's first sample: 30 idle samples
    (0 V +- noise) before the switch-on and 10 after a switch-off (an open relay: 0 V, 0 A) are cut,
    each with a note; the powered samples are the log's, at their own times."""
    rng = np.random.default_rng(3)
    powered = _rows(60)
    idle = lambda t: (t, 0.02 * rng.standard_normal(), 0.01 * rng.standard_normal(), 101.3)  # noqa: E731
    rows = ([idle(-0.03 + k / 1000.0) for k in range(30)] + powered
            + [idle(0.06 + k / 1000.0) for k in range(10)])
    f = _write(tmp_path / "log.csv", "time,voltage,current,booster_pressure [kPa abs]", rows)
    log = read_bench_log(f, CFG)
    assert log.n == 60 + 1  # the switch-off's sample is kept: the motor was on until then
    assert log.time[0] == pytest.approx(0.0) and log.voltage[0] == pytest.approx(13.5)
    assert any("before its switch-on" in n and "30 samples" in n for n in log.notes)
    assert any("after its switch-off" in n and "9 samples" in n for n in log.notes)
    plain = read_bench_log(_write(tmp_path / "plain.csv", "time,voltage,current,booster_pressure [kPa abs]",
                                  powered), CFG)
    assert np.array_equal(log.current[:60], plain.current) and not plain.notes


def test_a_log_with_the_motor_never_on_is_refused(tmp_path):
    rows = [(k / 1000.0, 0.0, 0.0, 101.3) for k in range(50)]
    with pytest.raises(DataError, match="median supply voltage|motor powered"):
        read_bench_log(_write(tmp_path / "off.csv", "time,voltage,current,booster_pressure [kPa abs]", rows), CFG)
