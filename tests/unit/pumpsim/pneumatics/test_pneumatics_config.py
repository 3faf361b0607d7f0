"""Spec §8 configuration keys: validated like the rest (key path and limit in the message)."""
import pytest

from pumpsim.config import config_from_dict
from pumpsim.errors import ConfigError
from tests.conftest import apply_changes, example_dict

BAD = [
    ({"rotor.width": None}, "rotor.width"),
    ({"rotor.width": -0.01}, "rotor.width must be in (0, 1 m"),
    ({"rotor.width": 25.0}, "rotor.width must be in (0, 1 m"),  # 25 mm typed as metres
    ({"ports.inlet": [1.0, 0.5]}, "ports.inlet must have 0 < end - start < 2 pi"),
    ({"ports.inlet": "wide"}, "'ports.inlet' must be a list"),
    ({"ports.inlet": [1.0]}, "ports.inlet must be [start, end]"),
    ({"ports.inlet_width": 0.5}, "ports.inlet_width must be in (0, rotor.width"),
    ({"ports.discharge_coefficient": 1.5}, "ports.discharge_coefficient must be in (0, 1]"),
    ({"ports.colour": 1}, "unknown key 'ports.colour'"),
    ({"valve.type": "ball"}, "valve.type must be \"check\" or \"reed\""),
    ({"valve.type": "reed"}, "missing required key 'valve.mass'"),
    ({"valve.stiffness": 100.0}, "valve.stiffness is for type = \"reed\""),
    ({"leak.tip_gap": -1e-6}, "leak.tip_gap must be in [0, 1 mm]"),
    ({"leak.end_gap": 0.01}, "leak.end_gap must be in [0, 1 mm]"),
    ({"gas.gamma": 0.9}, "gas.gamma must be in (1, 2]"),
    ({"gas.heat_transfer": -1.0}, "gas.heat_transfer must be in [0, 1e6 W/(m^2 K)"),
    ({"gas.heat_transfer": 2e6}, "gas.heat_transfer must be in [0, 1e6 W/(m^2 K)"),
    ({"valve.discharge_coefficient": 0.0}, "valve.discharge_coefficient must be in (0, 1]"),
    ({"ports.check_discharge_coefficient": 1.2}, "ports.check_discharge_coefficient must be in (0, 1]"),
    ({"booster.volume": None}, "missing required key 'booster.volume'"),
    ({"booster.target": 2e5}, "booster.target must be in (0, booster.pressure"),
    ({"booster.pressure": 2e5}, "booster.pressure must be <= gas.atmosphere"),
    ({"motor.resistance": 0.0}, "motor.resistance must be > 0"),
    ({"motor.voltage": -13.5}, "motor.voltage must be > 0"),  # reversed supply: the pump turns backwards
    ({"motor.constant": None}, "missing required key 'motor.constant'"),
    ({"vane.slot_pressure": "rotor"}, "vane.slot_pressure must be"),
    ({"vane.tip_radius": 0.001}, "vane.tip_radius must be 0 or >= vane.thickness/2"),
    ({"motor": None}, "operation.mode = \"motor\" needs the [motor] table"),
    ({"booster": None}, "the gas model needs the [booster] table"),
]


@pytest.mark.parametrize("changes,message", BAD)
def test_gas_keys_rejected_with_key_and_limit(changes, message):
    with pytest.raises(ConfigError) as e:
        config_from_dict(apply_changes(example_dict("evp_booster"), changes))
    assert message in str(e.value)


def test_rotor_width_in_mm_is_refused_without_the_gas_tables_too():
    """rotor.width also feeds tip PV in design studies: the same registry limit applies."""
    with pytest.raises(ConfigError, match=r"rotor.width must be in \(0, 1 m"):
        config_from_dict(apply_changes(example_dict("ellipse_4vanes"), {"rotor.width": 10.0}))


def test_example_parses_and_mechanical_configs_are_unchanged():
    cfg = config_from_dict(example_dict("evp_booster"))
    assert cfg.pneumatic is not None and cfg.pneumatic.motor and cfg.mode == "motor"
    assert cfg.pneumatic.booster_target == 30000.0
    plain = config_from_dict(example_dict("ellipse_4vanes"))
    assert plain.pneumatic is None
    assert config_from_dict(apply_changes(example_dict("ellipse_4vanes"), {"rotor.width": 0.02})).pneumatic is None


def test_motor_mode_without_gas_tables_is_rejected():
    with pytest.raises(ConfigError, match="needs the \\[motor\\] table and the gas tables"):
        config_from_dict(apply_changes(example_dict("ellipse_4vanes"), {"operation.mode": "motor"}))
