"""Sphinx directive ``.. pumpsim-config-keys::``: every configuration key, generated at build time.

The key list, types, required flags and defaults come from the config schema (``pumpsim.config``);
units, allowed ranges, derived defaults and descriptions from the parameter registry
(``pumpsim.model_spec.parameters``), ``housing.shape`` and the shapes' keys from the housing-shape
registry (``pumpsim.model_spec.housings``). Keys that are not registry numbers (lists, the operating
point) and registry entries without a description get theirs from ``EXTRA`` below. A key with no
description at all is a build warning, so the page cannot fall behind the code (``make docs``
treats warnings as errors). The tables are plain reStructuredText from `rst_lines`, which needs no
Sphinx (the test suite checks it).
"""
from __future__ import annotations

import math

from pathlib import Path

# key -> (unit, description) for what the registry does not describe. A unit of "" keeps the
# registry's. Choices are spelled out here; the registry holds numbers only.
EXTRA = {
    "name": ("-", "The pump's name, used in messages, figures and reports (default: the file name)."),
    "housing.center": ("m", "``[x, y]``: the housing centre relative to the rotor axis. A non-zero "
                            "centre is an eccentric rotor."),
    "housing.angle": ("", "Rotation ψ of the housing shape (semi-axes and harmonics) about its centre."),
    "housing.harmonics": ("m, rad", "Out-of-round terms ``[[k, A_k, γ_k], ...]``: the radius about the "
                                    "centre gains Σ A_k cos(k(α − ψ − γ_k)), α the polar angle. Order k an "
                                    "integer ≥ 1; the amplitude below 10 % of the housing size."),
    "rotor.radius": ("", "Rotor radius R_r."),
    "rotor.inertia": ("", "Polar inertia of everything that turns between the torque sensor and the "
                          "vanes (rotor, shaft, coupling)."),
    "rotor.vanes": ("-", "Number of vanes N ≥ 1, in equally spaced slots."),
    "rotor.slot_radius": ("", "Distance r_b from the rotor axis to the slot bottom, along the slot."),
    "rotor.slot_tilt": ("", "Slot tilt β from the radial direction (0: radial slots)."),
    "rotor.first_slot_angle": ("", "Angle of slot 0 in the rotor frame; slot i lies at this + 2π i/N."),
    "vane.length": ("", "Vane length L, from its bottom end to its tip."),
    "vane.thickness": ("", "Vane thickness h (the slot width)."),
    "vane.mass": ("", "Mass of one vane."),
    "vane.tip_radius": ("", "Radius ρ of a rounded tip; 0: a sharp tip on the centre line."),
    "vane.slot_pressure": ("Pa or -", 'Where the slot bottoms are vented: ``"inlet"``, ``"exhaust"``, '
                                      '``"atmosphere"`` or a pressure. It pushes each vane outwards with '
                                      "p × h × width."),
    "contact.housing.law": ("-", "Penalty law of the tip contact (contact model only): ``linear``, "
                                 "``hunt-crossley``, ``impact`` or ``report-nonlinear``."),
    "contact.bottom.law": ("-", "Penalty law of the slot-bottom contact; default: as the housing's."),
    "contact.housing.stiffness": ("", "Contact stiffness k (k δ^e); the contact model needs it."),
    "contact.housing.exponent": ("", "Force exponent e of the penetration δ."),
    "contact.housing.damping": ("", "Damping coefficient (its maximum for the ``impact`` law)."),
    "contact.housing.depth": ("", "Penetration over which the ``impact`` law's damping rises from "
                                  "0 to its maximum."),
    "contact.bottom.stiffness": ("", "As ``contact.housing.stiffness``, at the slot bottom."),
    "contact.bottom.exponent": ("", "As ``contact.housing.exponent``, at the slot bottom."),
    "contact.bottom.damping": ("", "As ``contact.housing.damping``, at the slot bottom."),
    "contact.bottom.depth": ("", "As ``contact.housing.depth``, at the slot bottom."),
    "operation.mode": ("-", '``"speed"``: the speed is prescribed and the torque computed; '
                            '``"torque"``: a drive torque is given and the speed follows; ``"motor"``: '
                            "a DC motor drives the pump (needs the gas tables and ``[motor]``)."),
    "operation.speed": ("rad/s", "Shaft speed (``speed`` mode); the start speed in ``torque`` and "
                                 "``motor`` mode (default 0)."),
    "operation.speed_rpm": ("rpm", "The same in revolutions per minute; give one of the two."),
    "operation.angle": ("rad", "Rotor angle θ at t = 0."),
    "operation.torque": ("N m", "Drive torque (``torque`` mode)."),
    "operation.bearing_torque": ("", "Constant bearing friction torque on the rotor."),
    "operation.initial_vane_state": ("-", 'Contact model start: ``"bottom"`` (vanes on the slot bottom), '
                                          '``"rotor"`` (at the constrained position, moving with the rotor; '
                                          'default) or ``"housing"`` (constrained position and velocity).'),
    "operation.speed_tolerance": ("-", "Relative band in which ``diagnose`` may refine the configured "
                                       "speed of a record without a speed column."),
    "effects.vane_friction_factors": ("-", "One COF factor per vane (tip and slot), N numbers ≥ 0; "
                                           "default all 1."),
    "effects.speed_ripple": ("-, -, rad", "``[order, relative amplitude, phase]``: a shaft-synchronous "
                                          "speed ripple ω(1 + A cos(kθ − φ)) in ``speed`` mode."),
    "gas.gas_constant": ("", "Specific gas constant (air: 287.05)."),
    "gas.wall_temperature": ("", "Wall temperature for the cells' heat exchange; default: "
                                 "``gas.temperature``."),
    "ports.inlet": ("rad", "Inlet window ``[start, end]`` in housing polar angle (housing frame)."),
    "ports.exhaust": ("rad", "Exhaust window ``[start, end]`` in housing polar angle (housing frame)."),
    "ports.width": ("m", "Axial width of both windows (when ``inlet_width``/``exhaust_width`` are not given)."),
    "ports.exhaust_width": ("", "Axial width of the exhaust window."),
    "ports.hose_diameter": ("m", "Diameter of the booster hose orifice."),
    "valve.type": ("-", 'Exhaust valve: ``"check"`` (area grows from cracking to full open) or '
                        '``"reed"`` (a sprung plate with mass, damping, preload and a stop).'),
    "valve.port_area": ("m^2", "Reed: port area, the cap of the curtain flow area; default π d²/4."),
    "valve.stiffness": ("", "Reed: spring stiffness."),
    "valve.damping": ("", "Reed: damping coefficient."),
    "valve.preload": ("", "Reed: spring preload holding the valve shut."),
    "valve.area": ("", "Check valve: full flow area (default: a 4 mm bore)."),
    "leak.tip_gap": ("", "Radial gap between vane tip and housing (leak between neighbouring cells)."),
    "leak.end_gap": ("", "Axial gap at each end face of the vanes."),
    "booster.volume": ("", "Brake-booster volume."),
    "booster.pressure": ("Pa", "Booster pressure at the start (absolute); default: the atmosphere."),
    "booster.target": ("Pa", "Pump-down target pressure (absolute); ``pumpdown --until`` overrides it."),
    "motor.resistance": ("", "Armature resistance (with leads and brushes)."),
    "motor.inductance": ("", "Armature inductance."),
}

# config key -> the registry entry that holds its unit and limits (the config sets it under
# another name, or as a list / a derived quantity)
REGISTRY_OF = {
    "housing.center": "housing.center.0",
    "effects.vane_friction_factors": "effects.vane_friction_factor.0",
    "ports.width": "ports.inlet.width",
    "ports.inlet_width": "ports.inlet.width",
    "ports.exhaust_width": "ports.exhaust.width",
    "valve.port_area": "valve.area",
}

SECTION_TITLES = {
    "": "Top level", "housing": "[housing]", "rotor": "[rotor]", "vane": "[vane]",
    "friction.housing": "[friction.housing]: vane tip on the housing",
    "friction.slot": "[friction.slot]: vane in its slot (omitted: as [friction.housing])",
    "contact.housing": "[contact.housing]: contact model only",
    "contact.bottom": "[contact.bottom]: contact model only (omitted: as [contact.housing])",
    "operation": "[operation]", "effects": "[effects]: known defects, e.g. from a diagnosis",
    "gas": "[gas]", "ports": "[ports]", "valve": "[valve]: the exhaust valve", "leak": "[leak]",
    "booster": "[booster]", "motor": "[motor]",
}
GAS_SECTIONS = ("gas", "ports", "valve", "leak", "booster", "motor")
# keys that lead their table (what decides the others), then the schema's order
FIRST = {"housing": ("shape", "<shape keys>", "center", "angle", "harmonics"), "rotor": ("vanes",),
         "operation": ("mode", "speed", "speed_rpm", "torque", "angle"), "valve": ("type",),
         "contact.housing": ("law",), "contact.bottom": ("law",)}
EMPTY = "–"  # an empty cell (a bare "-" would be a list item)


def _keys(schema: dict, prefix: str = ""):
    for k, v in schema.items():
        if isinstance(v, dict):
            yield from _keys(v, f"{prefix}{k}.")
        elif not k.startswith("__"):
            yield f"{prefix}{k}", v


UNIT_SIGNS = {"^2": "²", "^3": "³", "^e": "ᵉ", "ohm": "Ω"}
# a typical range in the unit an engineer reads it in (the config itself stays SI)
ENGINEERING = {"m": ((1e-3, "mm"), (1e-6, "µm")), "kg": ((1e-3, "g"),), "m/s": ((1e-3, "mm/s"),)}


def _unit(text: str) -> str:
    for plain, sign in UNIT_SIGNS.items():
        text = text.replace(plain, sign)
    return text


def _number(v) -> str:
    return f"{v:g}" if isinstance(v, (int, float)) and not isinstance(v, bool) else repr(v)


def _bound(b) -> str:
    if isinstance(b.value, str):
        return b.value if b.factor == 1 else f"{b.factor:g} × {b.value}"
    return b.label or _number(b.value)


def _range(q) -> str:
    lo_inf = not isinstance(q.lower.value, str) and math.isinf(q.lower.value)
    hi_inf = not isinstance(q.upper.value, str) and math.isinf(q.upper.value)
    if lo_inf and hi_inf:
        text = "any"
    elif hi_inf:
        text = f"{'>' if q.lower.open else '≥'} {_bound(q.lower)}"
    elif lo_inf:
        text = f"{'<' if q.upper.open else '≤'} {_bound(q.upper)}"
    else:
        text = (f"{'(' if q.lower.open else '['}{_bound(q.lower)}, {_bound(q.upper)}"
                f"{')' if q.upper.open else ']'}")
    if q.below:
        text += f"; < {q.below}"
    return text


def _typical(q) -> str:
    if q is None or q.plausible is None:
        return ""
    numbers = [b for b in q.plausible if not isinstance(b, str) and b != 0]
    scale, unit = 1.0, q.unit
    for factor, name in ENGINEERING.get(q.unit, ()):
        if numbers and min(abs(b) for b in numbers) / factor >= 0.1:  # the largest unit reading >= 0.1
            scale, unit = factor, name
            break
    lo, hi = (_number(b / scale) if not isinstance(b, str) else b for b in q.plausible)
    unit = "" if unit == "-" else f" {_unit(unit)}"
    shown = f"{lo} to {hi}{unit}" if not any(isinstance(b, str) for b in q.plausible) else f"[{lo}, {hi}]"
    return f"typical {shown}" + (f": {q.plausible_why}" if q.plausible_why else "")


def _default(kind, required, default, q) -> str:
    if required:
        return "required"
    if default is not None:
        if isinstance(default, list):
            return "``[]``" if not default else f"``{default!r}``"
        return f"``{default}``" if isinstance(default, str) else _number(default)
    if q is not None and q.derived:
        return f"``{q.derived}``"
    return EMPTY


def _quoted(items, last="or") -> str:
    items = [f"``{x}``" for x in items]
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} {last} {items[-1]}"


def housing_shapes() -> dict:
    """key -> (registry entry or None, description) of housing.shape and every housing shape's
    keys, from the housing-shape registry (``pumpsim.model_spec.housings``)."""
    from pumpsim.config import shape_key_parameter
    from pumpsim.model_spec import housings

    shapes = "; ".join(f'``"{s.name}"``: {s.description} (give {_quoted([k.name for k in s.keys], "and")})'
                       for s in housings.SHAPES.values())
    out = {"housing.shape": (None, f"One of the registered shapes: {shapes}. Each sets the compiled "
                                   "base curve, an ellipse with semi-axes ``housing.a``, ``housing.b``, "
                                   "to which ``harmonics`` add.")}
    for name, owners in housings.keys().items():
        k = housings.key(name)
        required = _quoted([f'shape = "{s}"' for s in owners])
        out[k.path] = (shape_key_parameter(k), f"{k.doc}; required for {required}.")
    return out


def _first(section: str) -> tuple:
    """The keys that lead `section`'s table, the housing shapes' keys in the registry's order."""
    from pumpsim.model_spec import housings

    lead = FIRST.get(section, ())
    if "<shape keys>" in lead:
        i = lead.index("<shape keys>")
        lead = (*lead[:i], *housings.keys(), *lead[i + 1:])
    return lead


def rows():
    """(section, key, type, unit, default, range, description) for every config key."""
    from pumpsim.config import schema
    from pumpsim.model_spec import parameters as P

    reg = {q.name: q for q in P.layout(P.Structure("contact", 1, 1))}
    reg.update({q.name: q for q in P.GAS_PARAMETERS})
    reg.update({q.name: q for q in P._harmonic(0)})
    for name, config_key in P.GAS_CONFIG_KEYS.items():
        REGISTRY_OF.setdefault(config_key, name)
    shapes = housing_shapes()
    out, missing = [], []
    for key, (kind, required, default) in _keys(schema()):
        q = reg.get(REGISTRY_OF.get(key, key))
        unit, text = EXTRA.get(key, ("", ""))
        if key in shapes:
            q, text = shapes[key]
            unit = unit or ("-" if q is None else "")
        unit = _unit(unit or (q.unit if q is not None else ""))
        doc = text or (q.doc[:1].upper() + q.doc[1:] + "." if q is not None and q.doc else "")
        if not doc:
            missing.append(key)
        extra = [] if q is None else [_range(q)]
        typical = _typical(q)
        if typical:
            extra.append(typical)
        section = key.rsplit(".", 1)[0] if "." in key else ""
        out.append((section, key.rsplit(".", 1)[-1], kind, unit, _default(kind, required, default, q),
                    "; ".join(extra), doc))
    return out, missing


def rst_lines(which: str) -> list[str]:
    """The tables of the "mechanical" or the "gas" configuration sections, as reStructuredText."""
    table, _ = rows()
    lines = []
    for section in dict.fromkeys(r[0] for r in table):
        keys = [r for r in table if r[0] == section]
        if section in ("rotor", "vane"):  # their gas-model keys go with the gas tables
            keys = [r for r in keys if (r[1] in ("width", "slot_pressure")) == (which == "gas")]
        elif (section in GAS_SECTIONS) != (which == "gas"):
            continue
        if not keys:
            continue
        lead = _first(section)
        keys.sort(key=lambda r: lead.index(r[1]) if r[1] in lead else len(lead))
        title = SECTION_TITLES.get(section, f"[{section}]")
        if which == "gas" and section in ("rotor", "vane"):
            title = f"[{section}]: the gas model's keys"
        lines += [title, "~" * len(title), "", ".. list-table::", "   :header-rows: 1",
                  "   :widths: 16 9 12 20 43", "   :class: config-keys", "",
                  "   * - key", "     - unit", "     - default", "     - allowed", "     - description"]
        for _, key, _kind, unit, default, allowed, doc in keys:
            lines += [f"   * - ``{key}``", f"     - {unit if unit not in ('', '-') else EMPTY}",
                      f"     - {default}", f"     - {allowed or EMPTY}", f"     - {doc}"]
        lines.append("")
    return lines


def setup(app):
    from docutils import nodes
    from docutils.statemachine import StringList
    from sphinx.util import logging
    from sphinx.util.docutils import SphinxDirective
    from sphinx.util.nodes import nested_parse_with_titles

    logger = logging.getLogger(__name__)

    class ConfigKeys(SphinxDirective):
        """One table per config section: key, unit, default, allowed range, description."""

        has_content = False
        option_spec = {"sections": lambda s: s}  # "mechanical" or "gas"

        def run(self):
            import pumpsim.config
            import pumpsim.model_spec.housings
            import pumpsim.model_spec.parameters
            import pumpsim.pneumatics.config

            # the page follows the registries and the schema
            for module in (pumpsim.config, pumpsim.model_spec.housings, pumpsim.model_spec.parameters,
                           pumpsim.pneumatics.config):
                self.env.note_dependency(module.__file__)
            self.env.note_dependency(__file__)
            for key in rows()[1]:
                logger.warning(f"config key {key} has no description (registry doc, or EXTRA in "
                               f"{Path(__file__).name})", location=self.get_location())
            node = nodes.section()
            node.document = self.state.document
            lines = rst_lines(self.options.get("sections", "mechanical"))
            nested_parse_with_titles(self.state, StringList(lines, source="pumpsim-config-keys"), node)
            return node.children

    app.add_directive("pumpsim-config-keys", ConfigKeys)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
