"""Cell geometry (spec §8): the N cells between neighbouring vanes, as CasADi expressions in the
parameter vector (a dimension change never recompiles).

Cell i lies between vane i and vane i+1, bounded by the housing arc between the two tip contacts,
the rotor circle and the two vanes' faces outside the rotor. Its area follows from Green's theorem,
A = 1/2 oint (x dy - y dx), around the counter-clockwise boundary

  E_i+ -> T_i+            straight: vane i's +w face, from the rotor circle to the tip
  T_i+ -> C_i             vane i's tip: flat end (rho = 0, C = B) or tip arc about P (rho > 0)
  C_i -> C_{i+1}          housing arc, alpha_i .. alpha_{i+1}: Gauss-Legendre on the smooth curve
  C_{i+1} -> T_{i+1}-     vane i+1's tip
  T_{i+1}- -> E_{i+1}-    vane i+1's -w face
  E_{i+1}- -> E_i+        rotor circle, clockwise

With the flank out of the rotor, E is where the face meets the rotor circle and T the flank's end
at the tip (J); where a round tip's flank ends inside the rotor, E = T is where the tip arc crosses
the rotor circle, so the slot mouth beside the cap is outside every cell (spec: cells bounded by
the rotor circle) and only the cap's part outside the rotor is loaded.

(straight piece: 1/2 X1 x X2; circle arc of radius r about P: 1/2 [P x (X2 - X1) + r^2 dphi]).
Every vane-side piece is shared with the vane outline, so Sum cells + Sum vane area outside the
rotor = housing area - pi R_r^2 holds by construction; the tests check it against independent
integrals. The gas force on each vane-side piece is p W (dy, -dx) (the outward normal integrated
along the piece), acting at the midpoint of a straight piece and through P for the tip arc; with the
rigid vane velocity field its power is exactly p dV/dt of that piece (Reynolds), so the virtual
power of the pressure loads equals Sum p_i dV_i/dt.
"""
from __future__ import annotations


import casadi as ca
import numpy as np

from .housing import TWO_PI, base_radius, base_sector_area

# Gauss-Legendre nodes for the harmonic part of a cell's housing-arc area (the ellipse part is
# closed form): the integrand is analytic and small (A_k / r ~ 1e-3); 32 nodes reach rounding
# for orders up to ~10 over a full turn (tests compare with adaptive quadrature).
HARMONIC_NODES = 32
PORT_NODES = 3  # arc length of a port overlap


def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _gl(n):
    x, w = np.polynomial.legendre.leggauss(n)
    return [float(v) for v in x], [float(v) for v in w]


class CellGeometry:
    """Cell areas, their theta-derivatives and port overlaps on a Model 2 builder `b`."""

    def __init__(self, b):
        self.b = b
        al = ca.SX.sym("alpha")
        h = b.housing(al)
        dC = ca.jacobian(h["C"], al)
        self.curve = ca.Function("housing_dC", [al, b.p], [h["C"], dC], {"cse": True})

    # -- one vane's outline (rotor frame) -------------------------------------------------------
    def outline(self, theta, phi, s, alpha):
        b = self.b
        g = b.geometry()
        m = b.mech(phi=phi, s=s, **g)
        Ob, u, w, B, P = m["Ob"], m["u"], m["w"], m["B"], m["P"]
        h, rho, Rr = g["h"], g["rho"], g["rotor_radius"]
        C = b.to_rotor(theta, b.housing(alpha)["C"])

        def rotor_hit(side):  # face line Ob + side h/2 w + a u meets the rotor circle
            q = Ob + side * h / 2 * w
            qu = ca.dot(q, u)
            a = -qu + ca.sqrt(qu * qu - ca.dot(q, q) + Rr * Rr)
            return q + a * u

        Rp, Rm = rotor_hit(1.0), rotor_hit(-1.0)
        round_tip = rho > 0
        sin_e = h / 2 / ca.if_else(round_tip, rho, 1.0)
        # floor: a full-round tip (rho = h/2) has cos = 0, where sqrt's slope is infinite; the
        # floor keeps the (structurally zero) state derivative of this parameter term finite
        cos_e = ca.sqrt(ca.fmax(1 - sin_e * sin_e, 1e-300))
        Jp = ca.if_else(round_tip, P + rho * (cos_e * u + sin_e * w), B + h / 2 * w)
        Jm = ca.if_else(round_tip, P + rho * (cos_e * u - sin_e * w), B - h / 2 * w)
        # tip contact point and its angle on the tip arc, measured from u towards w
        gam = ca.atan2(ca.dot(C - P, w), ca.dot(C - P, u))
        eps = ca.atan2(sin_e, cos_e)
        G = Ob + (s + g["L"] / 2) * u
        o = dict(Ob=Ob, A=m["A"], u=u, w=w, P=P, C=C, Rp=Rp, Rm=Rm, Jp=Jp, Jm=Jm, gam=gam,
                 eps=eps, rho=rho, round=round_tip, G=G)
        for side, key in ((1.0, "p"), (-1.0, "m")):
            o.update({k + key: v for k, v in self._wetted_start(o, side, Rr).items()})
        return o

    @staticmethod
    def _wetted_start(o, side, Rr):
        """Where the cell's boundary leaves the rotor circle on the vane's side `side` (E), where
        its tip piece starts (T) and that point's angle on the tip arc (t). The cell is bounded by
        the rotor circle: where a round tip's flank ends inside the rotor, the slot mouth beside
        the cap is not the cell's, and the boundary meets the cap where the cap crosses the rotor
        circle (face piece E -> T of zero length)."""
        J, R = (o["Jp"], o["Rp"]) if side > 0 else (o["Jm"], o["Rm"])
        P, u, w, rho = o["P"], o["u"], o["w"], o["rho"]
        inside = ca.logic_and(o["round"], ca.dot(J - R, u) < 0)
        # the cap circle (P, rho) meets |x| = Rr at a e +- hh e_perp; take the one on this side
        d = ca.norm_2(P)
        e = P / d
        a = (Rr * Rr - rho * rho + d * d) / (2 * d)
        # floor: the branch is unused where the circles do not meet; keeps its derivative finite
        hh = ca.sqrt(ca.fmax(Rr * Rr - a * a, 1e-300))
        perp = ca.vertcat(-e[1], e[0])
        X = a * e + hh * ca.sign(side * ca.dot(perp, w)) * perp
        t = ca.atan2(ca.dot(X - P, w), ca.dot(X - P, u))
        return dict(E=ca.if_else(inside, X, R), T=ca.if_else(inside, X, J),
                    t=ca.if_else(inside, t, side * o["eps"]))

    @staticmethod
    def _tip_piece(o, forward):
        """Green term and (force per unit p W, application point) of the tip from J+ to C
        (forward, cell on the +w side) or from C to J- (cell on the -w side)."""
        if forward:
            X1, X2, dphi = o["Tp"], o["C"], o["gam"] - o["tp"]
        else:
            X1, X2, dphi = o["C"], o["Tm"], o["tm"] - o["gam"]
        arc = 0.5 * (_cross(o["P"], X2 - X1) + o["rho"] ** 2 * dphi)
        green = ca.if_else(o["round"], arc, 0.5 * _cross(X1, X2))
        force = ca.vertcat(X2[1] - X1[1], -(X2[0] - X1[0]))
        where = ca.if_else(o["round"], o["P"], 0.5 * (X1 + X2))
        return green, force, where

    @staticmethod
    def _face_piece(o, forward):
        X1, X2 = (o["Ep"], o["Tp"]) if forward else (o["Tm"], o["Em"])
        return 0.5 * _cross(X1, X2), ca.vertcat(X2[1] - X1[1], -(X2[0] - X1[0])), 0.5 * (X1 + X2)

    def vane_pieces(self, o):
        """Pieces of vane i's outline facing cell i (+w side, 'lead') and cell i-1 ('trail'):
        lists of (force per unit p W, application point); and the vane's area outside the rotor."""
        face_p, tip_p = self._face_piece(o, True), self._tip_piece(o, True)
        tip_m, face_m = self._tip_piece(o, False), self._face_piece(o, False)
        Rr = self.b.geometry()["rotor_radius"]
        dphi = ca.atan2(o["Ep"][1], o["Ep"][0]) - ca.atan2(o["Em"][1], o["Em"][0])
        dphi = dphi - TWO_PI * ca.floor(dphi / TWO_PI)
        # vane outline counter-clockwise = reverse of the cells' pieces, closed along the rotor
        area = -(face_p[0] + tip_p[0] + tip_m[0] + face_m[0]) - 0.5 * Rr * Rr * dphi
        return ([face_p[1:], tip_p[1:]], [tip_m[1:], face_m[1:]],
                face_p[0] + tip_p[0], tip_m[0] + face_m[0], area)

    # -- housing arcs --------------------------------------------------------------------------
    def arc_integrals(self, a0, span, full_turn=False):
        """(1/2 int C x C' dalpha, arc length) over alpha in [a0, a0 + span].

        With C = c + r(alpha) e(alpha): C x C' = r^2 + d/dalpha [r (cx sin alpha - cy cos alpha)],
        and the base curve's 1/2 int r0^2 is its sector area in closed form (codegen/housing.py),
        so only the harmonic part r^2 - r0^2 (small) needs quadrature:
        Gauss-Legendre with HARMONIC_NODES nodes (none without harmonics). The arc length (only
        for the wall area of the heat exchange) is the mean-radius estimate r(mid) * span."""
        b = self.b
        P = b.P
        a, bb, psi = P["housing.a"], P["housing.b"], P["housing.angle"]
        cx, cy = P["housing.center.0"], P["housing.center.1"]
        a1 = a0 + span
        green = base_sector_area(a, bb, psi, a0, a1, full_turn, ca)

        def radius(al):
            return b.housing(al)["r"]

        def r0(al):
            return base_radius(a, bb, al, psi, ca)

        green += 0.5 * (radius(a1) * (cx * ca.sin(a1) - cy * ca.cos(a1))
                        - radius(a0) * (cx * ca.sin(a0) - cy * ca.cos(a0)))
        if b.st.harmonics:
            xs, ws = _gl(HARMONIC_NODES)
            acc = 0.0
            for x, wt in zip(xs, ws):
                al = a0 + 0.5 * span * (x + 1)
                r, rb = radius(al), r0(al)
                acc += wt * (r - rb) * (r + rb)
            green += 0.25 * span * acc
        return green, radius(a0 + 0.5 * span) * span

    def overlap_length(self, a0, span, start, end):
        """Arc length of [a0, a0 + span] (alpha) inside the window [start, end] (mod 2 pi):
        PORT_NODES-point Gauss-Legendre of |C'| on the overlap (a flow area, ~1e-5 accurate).
        With span <= 2 pi and a window shorter than 2 pi only two of the window's copies
        start + 2 pi k can meet the arc: the last one starting at or before a0, and the next."""
        xs, ws = _gl(PORT_NODES)
        total = 0.0
        k0 = ca.floor((a0 - start) / TWO_PI)
        for k in (k0, k0 + 1):
            lo = ca.fmax(a0, start + TWO_PI * k)
            hi = ca.fmin(a0 + span, end + TWO_PI * k)
            d = ca.fmax(hi - lo, 0.0)
            acc = 0.0
            for x, wt in zip(xs, ws):
                acc += wt * ca.norm_2(self.curve(lo + 0.5 * d * (x + 1), self.b.p)[1])
            total += 0.5 * d * acc
        return total

    # -- all cells -----------------------------------------------------------------------------
    def cells(self, theta, s, alpha):
        """Per cell: area (m^2), housing arc length, rotor arc length, flank lengths, the arc
        span in alpha, and per vane the outline and its area outside the rotor."""
        b = self.b
        N = b.st.vanes
        phis = b.slot_angles(b.p)
        outl = [self.outline(theta, phis[i], s[i], alpha[i]) for i in range(N)]
        pieces = [self.vane_pieces(o) for o in outl]
        Rr = b.geometry()["rotor_radius"]
        out = dict(area=[], arc=[], rotor_arc=[], a0=[], span=[], vane_area=[p[4] for p in pieces])
        for i in range(N):
            j = (i + 1) % N
            if N == 1:
                span = TWO_PI + 0.0 * alpha[0]
            else:
                d = alpha[j] - alpha[i]
                span = d - TWO_PI * ca.floor(d / TWO_PI)
            green_h, arc = self.arc_integrals(alpha[i], span, full_turn=N == 1)
            Rp, Rm = outl[i]["Ep"], outl[j]["Em"]
            dphi = ca.atan2(Rm[1], Rm[0]) - ca.atan2(Rp[1], Rp[0])
            dphi = dphi - TWO_PI * ca.floor(dphi / TWO_PI)
            if N == 1:
                dphi = ca.if_else(dphi <= 0, dphi + TWO_PI, dphi)
            area = pieces[i][2] + green_h + pieces[j][3] - 0.5 * Rr * Rr * dphi
            out["area"].append(area)
            out["arc"].append(arc)
            out["rotor_arc"].append(Rr * dphi)
            out["a0"].append(alpha[i])
            out["span"].append(span)
        out["outlines"], out["pieces"] = outl, pieces
        return out
