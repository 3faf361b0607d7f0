"""Specification limits (pumpsim.limits): the limits file's checks and what an estimate with its
95 % interval says against a limit."""
import pytest

from pumpsim import limits as spec
from pumpsim.errors import ConfigError
from pumpsim.identification.result import Estimate

FITTED = ["mu", "booster.leak", "motor.resistance"]


def write(tmp_path, text):
    p = tmp_path / "limits.toml"
    p.write_text(text)
    return p


def test_a_limits_file_reads_in_si_with_lower_and_or_upper(tmp_path):
    p = write(tmp_path, '[limits."booster.leak"]\nupper = 5e-5\n[limits.mu]\nlower = 0.12\nupper = 0.2\n')
    assert spec.read_limits(p, FITTED) == {"booster.leak": (None, 5e-5), "mu": (0.12, 0.2)}


@pytest.mark.parametrize("text, words", [
    ('[limits."motor.constant"]\nupper = 0.02\n', ['limits."motor.constant"', "not a fitted parameter", "--params"]),
    ('[limits."booster.lek"]\nupper = 1e-5\n', ["did you mean 'booster.leak'"]),
    ("[limits.mu]\nlower = 0.2\nupper = 0.1\n", ["limits.mu.lower (0.2) must be < upper (0.1)"]),
    ("[limits.mu]\nupper = 'high'\n", ["limits.mu.upper must be a finite number"]),
    ("[limits.mu]\nmax = 0.2\n", ["unknown key 'limits.mu.max'"]),
    ("[limits.mu]\n", ["limits.mu needs lower and/or upper"]),
    ("[limit.mu]\nupper = 0.2\n", ["unknown table 'limit'"]),
    ("[limits\nmu = 1\n", ["not valid TOML"]),
])
def test_bad_limits_name_the_file_and_the_key(tmp_path, text, words):
    p = write(tmp_path, text)
    with pytest.raises(ConfigError) as e:
        spec.read_limits(p, FITTED)
    assert str(p) in str(e.value)
    for w in words:
        assert w in str(e.value), str(e.value)


def test_a_missing_limits_file_is_named(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        spec.read_limits(tmp_path / "none.toml", FITTED)


@pytest.mark.parametrize("value, lo95, hi95, limit, expected", [
    (0.17, 0.168, 0.172, (0.12, 0.2), spec.IN),
    (2.7e-5, 2.5e-5, 2.9e-5, (None, 2.6e-5), spec.OUT),  # the estimate beyond: out, whatever the interval
    (0.11, 0.10, 0.12, (0.12, None), spec.OUT),
    (0.271, 0.2697, 0.2725, (0.2, 0.2715), spec.UNDECIDED),  # within, the interval reaches past
    (None, None, None, (0.0, 1.0), spec.NOT_CHECKED),
])
def test_status_of_an_estimate_against_a_limit(value, lo95, hi95, limit, expected):
    assert spec.status(value, lo95, hi95, limit) == expected


def test_statuses_are_not_judged_for_an_unusable_fit():
    est = {"mu": Estimate("mu", 0.3, 0.01, 0.28, 0.32, 0.15)}
    lim = {"mu": (None, 0.2), "booster.leak": (None, 1e-5)}
    assert spec.statuses(est, lim) == {"mu": spec.OUT, "booster.leak": spec.NOT_CHECKED}
    assert set(spec.statuses(est, lim, usable=False).values()) == {spec.NOT_JUDGED}
