"""Compiled kernels: loaded never stale, built when missing, evaluated over many samples.

- `cache`: the kernel folder -- building a variant through codegen's one entry point, listing
  and clearing the compiled libraries;
- `scalar`: a variant's CasADi functions (`load_kernels`) and their evaluation over samples;
- `simd`: the constrained model's inverse dynamics in SIMD lanes (`load_fast_kernel`,
  `fast_kernel`) and `sampled_inverse_dynamics`, which takes the fastest kernel available;
- `pneumatic`: the gas model's variant and parameter vector for a configuration.

The names below are this package's interface; the modules above sit under the simulation,
identification and design code and import none of it.
"""
from .cache import build_library, building_allowed, cached, clear, log_build, writable_dir
from .scalar import Kernels, default_threads, evaluate, inverse_dynamics, load_kernels, map_samples
from .simd import FAST_THREADED, fast_kernel, load_fast_kernel, sampled_inverse_dynamics

__all__ = ["FAST_THREADED", "Kernels", "build_library", "building_allowed", "cached", "clear",
           "default_threads", "evaluate", "fast_kernel", "inverse_dynamics", "load_fast_kernel",
           "load_kernels", "log_build", "map_samples", "sampled_inverse_dynamics", "writable_dir"]
