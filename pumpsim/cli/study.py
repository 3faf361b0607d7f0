"""`pumpsim study CONFIG`: the contact model's solver study (tolerances, stiffness, integrators)."""
from __future__ import annotations

from .common import Help, add_force, load_config, outputs, positive_float, staged


MIN_REVOLUTIONS = 2.0


def register(sub):
    st = sub.add_parser("study", help="contact-model solver study: tolerances, contact stiffness, integrators",
                        formatter_class=Help)
    st.add_argument("config", help="TOML configuration with [contact.housing]")
    st.add_argument("--revolutions", type=positive_float, default=10.0, help="revolutions simulated per setting")
    st.add_argument("--speed", type=positive_float, help="constant speed [rad/s] (default: the config's)")
    st.add_argument("--json", help="write the table as JSON")
    add_force(st)
    st.set_defaults(func=run)


def run(a) -> int:
    from ..errors import ConfigError
    from ..solver_study import HEADER, solver_study, write_json

    if a.revolutions < MIN_REVOLUTIONS:
        raise ConfigError(f"--revolutions must be >= {MIN_REVOLUTIONS:g}, got {a.revolutions:g}: the deviations are "
                          "taken over the last revolution, which must lie after the in-contact start")
    outs = outputs(a, [a.config], json=None)
    cfg = load_config(a)
    if not cfg.contact_given:
        raise ConfigError("the solver study needs [contact.housing] with a stiffness in the config")
    print(f"contact model solver study: {cfg.name}, constant speed, {a.revolutions:g} revolutions "
          "from an in-contact start; deviations from Model 2 over the last revolution")
    print(HEADER)
    result = solver_study(cfg, revolutions=a.revolutions, speed=a.speed, log=print)
    with staged(outs) as tmp:
        if a.json:
            write_json(tmp["--json"], result)
    return 0
