"""C text of an SX function's body as one `#pragma omp simd` loop over samples (codegen/simd.py's
library and its Jacobian entries): written from CasADi's own instruction list, one C statement per
SX instruction, so that gcc vectorises the loop with glibc's vector math (see codegen/simd.py)."""
from __future__ import annotations

import math
from collections import Counter

import casadi as ca

# Selects are written as bit blends (pz_sel), not C conditionals: from `c ? a : b` gcc builds
# branches, threads jumps through them and then cannot if-convert operations that might trap
# (-ftrapping-math) -- AVX-512 masks hide that, AVX2 loops stayed scalar. A blend has no branch.
_SEL = "pz_sel((int64_t)({c}), {a}, {b})"
_UNARY = {
    ca.OP_NEG: "(-{0})", ca.OP_SQ: "({0}*{0})", ca.OP_TWICE: "(2.*{0})", ca.OP_INV: "(1./{0})",
    ca.OP_FABS: "fabs({0})", ca.OP_SQRT: "sqrt({0})", ca.OP_SIN: "sin({0})",
    ca.OP_COS: "cos({0}+zero)",  # + zero: no sincos fusion (see codegen/simd.py)
    ca.OP_TAN: "tan({0})", ca.OP_EXP: "exp({0})", ca.OP_LOG: "log({0})", ca.OP_ATAN: "atan({0})",
    ca.OP_ASIN: "asin({0})", ca.OP_ACOS: "acos({0})", ca.OP_TANH: "tanh({0})",
    ca.OP_SINH: "sinh({0})", ca.OP_COSH: "cosh({0})", ca.OP_FLOOR: "floor({0})",
    ca.OP_CEIL: "ceil({0})", ca.OP_ERF: "erf({0})",
    ca.OP_NOT: _SEL.format(c="{0}==0.", a="1.", b="0."),
    # casadi_sign: -1, 1, or x itself (0, NaN)
    ca.OP_SIGN: _SEL.format(c="{0}<0.", a="-1.", b=_SEL.format(c="{0}>0.", a="1.", b="{0}")),
}
_BINARY = {
    ca.OP_ADD: "({0}+{1})", ca.OP_SUB: "({0}-{1})", ca.OP_MUL: "({0}*{1})", ca.OP_DIV: "({0}/{1})",
    ca.OP_LT: _SEL.format(c="{0}<{1}", a="1.", b="0."), ca.OP_LE: _SEL.format(c="{0}<={1}", a="1.", b="0."),
    ca.OP_EQ: _SEL.format(c="{0}=={1}", a="1.", b="0."), ca.OP_NE: _SEL.format(c="{0}!={1}", a="1.", b="0."),
    ca.OP_AND: _SEL.format(c="({0}!=0.)&({1}!=0.)", a="1.", b="0."),
    ca.OP_OR: _SEL.format(c="({0}!=0.)|({1}!=0.)", a="1.", b="0."),
    ca.OP_IF_ELSE_ZERO: _SEL.format(c="{0}!=0.", a="{1}", b="0."),
    # C99 fmax/fmin: the non-NaN operand
    ca.OP_FMAX: _SEL.format(c="({0}!={0})|({0}<{1})", a="{1}", b="{0}"),
    ca.OP_FMIN: _SEL.format(c="({0}!={0})|({1}<{0})", a="{1}", b="{0}"),
    ca.OP_POW: "pow({0},{1})", ca.OP_CONSTPOW: "pow({0},{1})", ca.OP_ATAN2: "atan2({0},{1})",
    ca.OP_COPYSIGN: "copysign({0},{1})", ca.OP_FMOD: "fmod({0},{1})",
}
HELPERS = r"""#include <stdint.h>
#include <string.h>
static inline uint64_t pz_bits(double x) { uint64_t u; memcpy(&u, &x, 8); return u; }
static inline double pz_dbl(uint64_t u) { double x; memcpy(&x, &u, 8); return x; }
/* c ? a : b as a bit blend (c is 0 or 1) */
static inline double pz_sel(int64_t c, double a, double b) {
  uint64_t m = (uint64_t)(-c);
  return pz_dbl((pz_bits(a) & m) | (pz_bits(b) & ~m));
}"""


# Inputs the emitter writes as C literals instead of reading them: a constant CasADi must not see
# (it folds x * (1 / y) back into x / y; gcc, without -freciprocal-math, keeps what is written)
LITERAL_INPUTS = {"pz_one": "1."}


def shared_reciprocals(f: ca.Function) -> ca.Function:
    """f with every quotient whose divisor divides more than once written as a product with that
    divisor's reciprocal, computed once (one division per divisor instead of one per quotient: the
    Cramer solves, the unit normals). The result may differ from f's in the last bit. The
    reciprocal is pz_one / y, with pz_one an extra last input (LITERAL_INPUTS): written 1 / y,
    CasADi would fold the products back into quotients. The quotient node becomes a product whose
    derivatives use its operands, not itself, so an entry that also takes derivatives of f
    (simd_jacobian) computes each product with the same uses -- and gcc contracts it into an FMA
    or not alike: their f-values stay the same bits."""
    sx_in = f.sx_in()
    _, divisors = _replay(f, sx_in)  # instruction -> its divisor's node hash
    uses = Counter(divisors.values())
    if max(uses.values(), default=0) < 2:
        return f
    one = ca.SX.sym("pz_one")
    reciprocal = {}

    def quotient(k, a, b):
        key = divisors[k]
        if uses[key] < 2:
            return ca.SX.binary(ca.OP_DIV, a, b)
        if key not in reciprocal:
            reciprocal[key] = ca.SX.binary(ca.OP_DIV, one, b)
        return ca.SX.binary(ca.OP_MUL, a, reciprocal[key])

    outs, _ = _replay(f, sx_in, quotient)
    return ca.Function(f.name(), [*sx_in, one], outs, [*f.name_in(), "pz_one"], f.name_out())


def _replay(f: ca.Function, sx_in, quotient=None):
    """f's instruction list evaluated on SX: (f's outputs, {division instruction: its divisor's
    node hash}); quotient(k, a, b) builds instruction k's a / b (default: the plain quotient)."""
    w, divisors = {}, {}
    outs = [ca.SX.zeros(f.sparsity_out(i)) for i in range(f.n_out())]
    for k in range(f.n_instructions()):
        op, ins, res = f.instruction_id(k), f.instruction_input(k), f.instruction_output(k)
        if op == ca.OP_INPUT:
            w[res[0]] = sx_in[ins[0]].nz[ins[1]]
        elif op == ca.OP_OUTPUT:
            outs[res[0]].nz[res[1]] = w[ins[0]]
        elif op == ca.OP_CONST:
            w[res[0]] = ca.SX(f.instruction_constant(k))
        elif op == ca.OP_DIV:
            a, b = w[ins[0]], w[ins[1]]
            divisors[k] = b.element_hash()
            w[res[0]] = quotient(k, a, b) if quotient else ca.SX.binary(ca.OP_DIV, a, b)
        elif len(ins) == 1 or op in _UNARY:
            w[res[0]] = ca.SX.unary(op, w[ins[0]])
        else:
            w[res[0]] = ca.SX.binary(op, w[ins[0]], w[ins[1]])
    return outs, divisors


def _const(x: float) -> str:
    if math.isnan(x):
        return "NAN"
    if math.isinf(x):
        return "INFINITY" if x > 0 else "(-INFINITY)"
    return repr(float(x))


def emit_loop(f: ca.Function, name: str, per_sample: set[int]) -> str:
    """C text of `static void name(long n, const double *const *in, double *const *out)`: f's SX
    body in one `omp simd` loop over n samples. in[] holds one pointer per input nonzero (inputs in
    order): for inputs in `per_sample` it points at n values (one per sample), otherwise at one
    value shared by all samples. out[] holds one pointer per output nonzero, to n values."""
    if not f.is_a("SXFunction"):
        raise TypeError(f"{f.name()} is not an SX function")
    nz_in = [f.nnz_in(i) for i in range(f.n_in())]
    off_in = [sum(nz_in[:i]) for i in range(len(nz_in))]
    nz_out = [f.nnz_out(i) for i in range(f.n_out())]
    off_out = [sum(nz_out[:i]) for i in range(len(nz_out))]
    head, body = [], []
    used_in = set()
    for k in range(f.n_instructions()):
        op = f.instruction_id(k)
        if op == ca.OP_INPUT:
            (i, j), (w,) = f.instruction_input(k), f.instruction_output(k)
            if f.name_in(i) in LITERAL_INPUTS:
                body.append(f"w{w} = {LITERAL_INPUTS[f.name_in(i)]};")
                continue
            q = off_in[i] + j
            used_in.add((q, i in per_sample))
            body.append(f"w{w} = x{q}[s];" if i in per_sample else f"w{w} = x{q};")
        elif op == ca.OP_OUTPUT:
            (w,), (i, j) = f.instruction_input(k), f.instruction_output(k)
            body.append(f"y{off_out[i] + j}[s] = w{w};")
        elif op == ca.OP_CONST:
            body.append(f"w{f.instruction_output(k)[0]} = {_const(f.instruction_constant(k))};")
        elif op in _UNARY:
            a = f.instruction_input(k)
            body.append(f"w{f.instruction_output(k)[0]} = " + _UNARY[op].format(f"w{a[0]}") + ";")
        elif op in _BINARY:
            a = f.instruction_input(k)
            body.append(f"w{f.instruction_output(k)[0]} = "
                        + _BINARY[op].format(f"w{a[0]}", f"w{a[1]}") + ";")
        else:
            raise NotImplementedError(f"{f.name()}: SX operation {op} has no SIMD form")
    for q, per in sorted(used_in):
        head.append(f"  const double *restrict x{q} = in[{q}];" if per else f"  const double x{q} = *in[{q}];")
    head += [f"  double *restrict y{q} = out[{q}];" for q in range(sum(nz_out))]
    work = ", ".join(f"w{w}" for w in range(f.sz_w()))
    return "\n".join([
        f"/* {f.name()}: {f.n_instructions()} SX instructions; per-sample inputs "
        f"{sorted(f.name_in(i) for i in per_sample)} */",
        f"static void {name}(long n, const double *const *in, double *const *out) {{",
        *head,
        "  const double zero = pumpsim_zero;",
        "  #pragma omp simd",
        "  for (long s = 0; s < n; ++s) {",
        f"    double {work};",
        *("    " + line for line in body),
        "  }",
        "}",
    ])
