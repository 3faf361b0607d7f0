"""The SIMD library's shared reciprocals (codegen.simd_emit.shared_reciprocals): one division per
divisor that divides more than once, the same function to rounding, the same derivatives, and a
reciprocal CasADi cannot fold back into quotients."""
import re

import casadi as ca
import numpy as np

from pumpsim.codegen.simd_emit import LITERAL_INPUTS, emit_loop, shared_reciprocals


def ops(f: ca.Function, op) -> int:
    return sum(f.instruction_id(k) == op for k in range(f.n_instructions()))


def example():
    x, y, z = (ca.SX.sym(n) for n in "xyz")
    n = ca.sqrt(x * x + y * y)  # a unit vector: two quotients by one norm
    out = ca.vertcat(x / n, y / n, ca.sin(x) / z, (x + y) / n)
    return ca.Function("f", [x, ca.vertcat(y, z)], [out, x / z], ["x", "yz"], ["u", "w"])


def test_a_divisor_used_three_times_divides_once():
    f = example()
    g = shared_reciprocals(f)
    # n divides three quotients: one reciprocal and three products; z divides twice: likewise
    assert ops(f, ca.OP_DIV) == 5 and ops(g, ca.OP_DIV) == 2
    assert ops(g, ca.OP_MUL) == ops(f, ca.OP_MUL) + 5
    assert g.name_in() == [*f.name_in(), "pz_one"] and g.name_out() == f.name_out()


def test_the_values_and_derivatives_agree_to_rounding():
    f, g = example(), shared_reciprocals(example())
    rng = np.random.default_rng(3)
    for _ in range(20):
        x, yz = rng.normal(), rng.normal(size=2)
        for a, b in zip(f(x, yz), g(x, yz, 1.0)):
            np.testing.assert_allclose(np.array(b), np.array(a), rtol=4e-16 * 4, atol=0)
    sx = g.sx_in()
    jf = ca.Function("jf", sx[:2], [ca.jacobian(f(*sx[:2])[0], ca.vertcat(*sx[:2]))])
    jg = ca.Function("jg", sx, [ca.jacobian(g(*sx)[0], ca.vertcat(*sx[:2]))])
    for _ in range(20):
        x, yz = rng.normal(), rng.normal(size=2)
        np.testing.assert_allclose(np.array(jg(x, yz, 1.0)), np.array(jf(x, yz)), rtol=1e-14, atol=1e-14)


def test_the_reciprocal_is_written_as_a_literal_one_and_not_folded():
    g = shared_reciprocals(example())
    c = emit_loop(g, "loop", {0, 1})
    assert f" = {LITERAL_INPUTS['pz_one']};" in c and "in[3]" not in c  # pz_one is input nonzero 3: never read
    # the products stay products: CasADi given a plain 1 / y folds x * (1 / y) back into x / y
    y = ca.SX.sym("y")
    assert str(ca.SX.sym("x") * (1 / y)) == "(x/y)"
    assert len(re.findall(r"\(w\d+/w\d+\)", c)) == ops(g, ca.OP_DIV) == 2


def test_a_function_without_shared_divisors_is_returned_as_it_is():
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    f = ca.Function("f", [x, y], [x / y + y / x])
    assert shared_reciprocals(f) is f
