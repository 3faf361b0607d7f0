"""A pump fit that no Gauss-Newton step leaves from its start. Started at the minimum a first fit
found (the diagnosis's refits start from such estimates), the reversal staircase makes every trial
step raise the cost: that start IS the minimum to the data's resolution (F test), reported
converged with that reason. A start that is not a minimum is reported NOT converged, in the JSON,
the text and the exit status (1: the fit is not a usable estimate)."""
import dataclasses
import math

import numpy as np
import pytest

import pumpsim
from pumpsim.cli.identify import unusable
from pumpsim.data import Dataset
from pumpsim.identification import identify
from pumpsim.identification.optimiser import START_NOT_MINIMUM
from tests.conftest import make_config

RATIO = 0.18 / 0.17


def cof(mu):
    return {"friction.housing.dynamic": mu, "friction.housing.static": mu * RATIO}


def record(base, theta0, seed, noise=0.02):
    truth = make_config(base, **cof(0.17), **{"operation.speed": 471.0})
    r = pumpsim.simulate(dataclasses.replace(truth, angle=theta0), duration=0.05, rate=10000)
    y = r.torque + np.random.default_rng(seed).normal(0, noise * np.std(r.torque), r.time.size)
    return Dataset(r.time, y)


@pytest.mark.parametrize("base,theta0,seed", [("ellipse_4vanes", 0.15, 0), ("ellipse_1vane", math.pi / 2, 2)])
def test_a_fit_started_at_its_own_minimum_is_converged_with_the_reason(base, theta0, seed):
    ds = record(base, theta0, seed)
    cfg = make_config(base, **cof(0.1), **{"operation.speed": 471.0})
    first = identify(cfg, ds, ["mu", "theta0"], initial={"theta0": theta0})
    at_min = {n: first.value(n) for n in ("mu", "theta0")}
    res = identify(cfg, ds, ["mu", "theta0"], initial=at_min, multistart=False)
    # measured: every trial step from the minimum raises the cost (the staircase); the smooth step
    # points 0.24 (4 vanes) and 0.55 (1 vane) standard errors away, F test p 0.97 and 0.86
    assert len(res.iterations) == 1 and res.value("mu") == at_min["mu"]
    assert res.converged and not res.problems()
    assert "cannot tell the start from a minimum" in res.message
    assert res.to_json()["converged"] is True
    assert str(res).splitlines()[0].endswith(res.message)


def test_a_start_that_is_not_a_minimum_reads_not_converged_everywhere(capsys):
    ds = record("ellipse_1vane", math.pi / 2, 2)
    cfg = make_config("ellipse_1vane", **cof(0.1), **{"operation.speed": 471.0})
    res = identify(cfg, ds, ["mu"], multistart=False)
    message = START_NOT_MINIMUM.format(se="12.5", p=1e-30, to="mu = 0.17")
    stalled = dataclasses.replace(res, converged=False, message=message, iterations=res.iterations[:1])
    assert stalled.to_json()["converged"] is False and stalled.to_json()["message"] == message
    head = str(stalled).splitlines()[0]
    assert "NOT converged after 0 iterations" in head and "NOT a minimum" in head and "--start" in head
    assert unusable(stalled.problems()) == 1
    assert f"NOT converged ({message})" in capsys.readouterr().err
