"""Which compiled variants a configuration or study file needs, and building them ahead of use
(`pumpsim kernels build`, `make codegen`: for CI images and clusters). Above the kernels and the
design studies: a study's variants are its designs' vane counts and housings."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .errors import CodegenError, KernelCacheError
from .kernels import load_kernels
from .model_spec.parameters import MODELS


def structures_of(path, models=None) -> list:
    """The compiled variants a configuration file needs (Model 2, or `models`; a gas config also its
    gas-cell variants), or a study file (one with [study]): every variant its designs use."""
    import tomllib

    from .config import load_config

    try:
        is_study = "study" in tomllib.loads(Path(path).read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        is_study = False  # load_config names the file and the problem
    if is_study:
        from .design.execute import structures
        from .design.study import load_study

        return list(dict.fromkeys(structures(load_study(path))))
    cfg = load_config(path)
    out = [cfg.structure_for(m) for m in models or ["constrained"]]
    if cfg.pneumatic is not None:  # spec §8 configs also get their gas-cell variant
        from .kernels.pneumatic import structure_of

        out += [structure_of(cfg, m) for m in ["constrained"] + (["contact"] if cfg.contact_given else [])]
    return list(dict.fromkeys(out))


def build_for(paths, models=None, simd: bool = True, log=print) -> None:
    """Load, building when missing or stale, every variant the files need (structures_of) and, with
    simd, the SIMD inverse dynamics of the Model 2 ones; one line per library."""
    from .kernels import load_fast_kernel

    seen = set()
    for path in paths:
        for st in structures_of(path, models):
            if st in seen:
                continue
            seen.add(st)
            log(f"{st.variant}: {load_kernels(st, build=True).folder}")
            if simd and st.model == "constrained":
                try:
                    log(f"{st.variant} (SIMD): {load_fast_kernel(st, build=True, fallback=False).folder}")
                except KernelCacheError:
                    raise
                except CodegenError as exc:  # the scalar kernel still works: say so, do not fail
                    log(f"{st.variant}: no SIMD library on this machine: {exc}")


def main(argv=None) -> int:  # python -m pumpsim.variants [--simd] CONFIG ... (make codegen)
    ap = argparse.ArgumentParser(description="Load (and build when missing or stale) the compiled "
                                             "kernels of configuration files.")
    ap.add_argument("configs", nargs="+", help="TOML configs whose variants to load")
    ap.add_argument("--model", choices=MODELS, action="append")
    ap.add_argument("--simd", action="store_true",
                    help="also the SIMD inverse dynamics of the constrained variants")
    args = ap.parse_args(argv)
    build_for(args.configs, args.model, simd=args.simd, log=lambda m: print(m, flush=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
