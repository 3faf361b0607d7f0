"""Gas laws of the pneumatic model (spec §8) as CasADi expressions.

Compressible isentropic orifice flow with choking in both directions (the textbook nozzle, as
PDSim's IsentropicNozzle): with r = p_down/p_up,
  unchoked  mdot = A p_up sqrt(2 g / ((g-1) R T_up) (r^(2/g) - r^((g+1)/g))),
  choked    (r < (2/(g+1))^(g/(g-1)))  mdot = A p_up sqrt(g / (R T_up)) (2/(g+1))^((g+1)/(2(g-1))).
A is the effective area (C_d times the geometric area). Near r = 1 the exact law has an infinite
slope dmdot/dp (a square root of the pressure difference), which a Newton-based stiff integrator
cannot use; above r = LINEAR_RATIO the flow function is continued linearly to zero at r = 1
(continuous, finite slope). The error is confined to pressure differences below 0.5 % of the
upstream pressure, where the flow is a few per cent of its choked value.
"""
from __future__ import annotations

import casadi as ca

LINEAR_RATIO = 0.995
PRESSURE_FLOOR = 1e-3  # Pa: keeps powers and roots defined if a trial step undershoots
TEMPERATURE_FLOOR = 1.0  # K: the same for a trial step's cell temperature


def _flow_function(r, g):
    """sqrt(2g/(g-1) (r^(2/g) - r^((g+1)/g))) with choking; per p_up / sqrt(R T_up)."""
    r_crit = (2 / (g + 1)) ** (g / (g - 1))
    rr = ca.fmax(r, r_crit)
    # one power per flow: with q = rr^(1/g), rr^(2/g) = q^2 and rr^((g+1)/g) = rr q
    q = rr ** (1 / g)
    return ca.sqrt(ca.fmax(2 * g / (g - 1) * (q * q - rr * q), 0.0))


def orifice_flow(p1, T1, p2, T2, area, R, g):
    """Signed mass flow from side 1 to side 2 through effective area `area` (kg/s)."""
    p1, p2 = ca.fmax(p1, PRESSURE_FLOOR), ca.fmax(p2, PRESSURE_FLOOR)
    forward = p1 >= p2
    pu = ca.if_else(forward, p1, p2)
    pd = ca.if_else(forward, p2, p1)
    Tu = ca.fmax(ca.if_else(forward, T1, T2), TEMPERATURE_FLOOR)
    r = pd / pu
    psi_lin = _flow_function(LINEAR_RATIO, g)
    # both branches are evaluated (and differentiated): the nozzle branch at r <= LINEAR_RATIO only,
    # where its square root has a finite slope
    psi = ca.if_else(r > LINEAR_RATIO, psi_lin * (1 - r) / (1 - LINEAR_RATIO),
                     _flow_function(ca.fmin(r, LINEAR_RATIO), g))
    m = area * pu / ca.sqrt(R * Tu) * psi
    return ca.if_else(forward, m, -m)


def choked_flux(p_up, T_up, R, g):
    """Choked mass flow per unit effective area (kg/(s m^2))."""
    return p_up / ca.sqrt(R * T_up) * ca.sqrt(g) * (2 / (g + 1)) ** ((g + 1) / (2 * (g - 1)))


def ramp(x, start, width):
    """0 below start, 1 above start + width, linear between (check-valve opening)."""
    return ca.fmin(ca.fmax((x - start) / width, 0.0), 1.0)


def enthalpy_flow(mdot, T_from, T_to, cp):
    """Enthalpy carried by a signed flow from side 'from' to side 'to' (upstream temperature)."""
    return cp * mdot * ca.if_else(mdot >= 0, T_from, T_to)
