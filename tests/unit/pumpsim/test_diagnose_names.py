"""The names diagnose reports: a `confounded` pair names effects (as the library declares them) or
baseline parameters, never a raw fitted parameter of an effect (spec §7: [[name, name], ...])."""
import pytest

from pumpsim.diagnosis.effects import EFFECTS, owner_of
from tests.conftest import make_config


@pytest.mark.parametrize("example", ["ellipse_4vanes", "test_rig"])
def test_every_fitted_name_of_an_effect_reads_as_that_effect(example):
    cfg = make_config(example)
    for e in EFFECTS:
        for k in e.orders(cfg):
            for name in e.params(cfg, k):
                assert owner_of(name, cfg) == e.name, (e.name, k, name)
                assert owner_of(name + "@1", cfg) == e.name  # a per-measurement copy too


def test_baseline_parameters_read_as_themselves():
    cfg = make_config("ellipse_4vanes")
    for name in ("mu", "theta0", "speed", "speed@0"):
        assert owner_of(name, cfg) == name.split("@")[0]
