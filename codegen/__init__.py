"""Code generation: SymPy mechanics -> CasADi functions -> C shared libraries in generated/."""
