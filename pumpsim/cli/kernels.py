"""`pumpsim kernels list | build | clear`: the compiled model kernels."""
from __future__ import annotations

from ..model_spec.manifest import GENERATED_ENV
from .common import Help, Parser


def register(sub):
    k = sub.add_parser("kernels", help="list, build or clear the compiled model kernels",
                       formatter_class=Help,
                       description="Compiled kernels (one C library per model variant) are built on first "
                       "use into a checkout's generated/ or, for an installed package, the per-user cache "
                       f"(~/.cache/pumpsim/kernels on Linux); {GENERATED_ENV}=DIR moves them (e.g. to a "
                       "shared, prebuilt folder on a cluster).")
    ks = k.add_subparsers(dest="action", required=True, parser_class=Parser)
    ks.add_parser("list", help="the kernels in the folder: variant, key, size, status, path")
    b = ks.add_parser("build", help="build (or check) the kernels that configs or studies need, "
                      "e.g. for a CI image or a cluster's shared folder", formatter_class=Help)
    b.add_argument("files", nargs="+", metavar="FILE", help="TOML configs or studies")
    b.add_argument("--model", choices=["constrained", "contact"], action="append",
                   help="models of a config (repeatable; default: constrained)")
    c = ks.add_parser("clear", help="remove the kernels (they are rebuilt on use)")
    c.add_argument("--stale", action="store_true",
                   help="only those this installation does not load (another model source, CasADi or CPU)")
    k.set_defaults(func=run)


def _megabytes(n: int) -> str:
    return f"{n / 1e6:.1f} MB"


def run(a) -> int:
    from .. import kernels
    from ..model_spec.manifest import generated_dir

    if a.action == "build":
        from ..variants import build_for

        build_for(a.files, a.model, log=lambda m: print(m, flush=True))
    elif a.action == "clear":
        gone = kernels.clear(stale_only=a.stale)
        print(f"removed {len(gone)} kernel folder(s), {_megabytes(sum(k['size'] for k in gone))}, "
              f"from {generated_dir()}")
    else:
        _list(kernels.cached(), generated_dir())
    return 0


def _list(found, folder) -> None:
    print(f"kernel folder: {folder} (set {GENERATED_ENV} to move it)")
    if found:
        w = max(len(k["variant"]) for k in found)
        print(f"{'variant':<{w}}  {'key':<20}  {'size':>8}  {'status':<7}  path")
    for k in found:
        print(f"{k['variant']:<{w}}  {k['key']:<20}  {_megabytes(k['size']):>8}  "
              f"{_status(k):<7}  {k['folder']}")
    print(f"{len(found)} kernel(s), {_megabytes(sum(k['size'] for k in found))}"
          + ("; stale: not recorded for this model source, CasADi or CPU (`pumpsim kernels clear --stale`)"
             if any(_status(k) == "stale" for k in found) else "")
          + ("; damaged: the library's bytes differ from its manifest (rebuilt when next used, or "
             "`pumpsim kernels clear --stale`)" if any(k.get("damaged") for k in found) else ""))


def _status(k) -> str:
    return "ok" if k["usable"] else "damaged" if k.get("damaged") else "stale"
