"""Independent implementation of spec §1-7 (Model 2) for benchmarking diagnose on data it was not built from."""
