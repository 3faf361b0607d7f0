"""Where compiled variants live and when one may be trusted: the cache key and the manifest.

A variant folder `<variant>-<key>/` in generated_dir() holds the generated C source, the library and
`manifest.json`. Two hashes, two questions:

- the **key** (content key) hashes what the library is made of: the generated C source, the
  codegen options (exported derivatives, compiler flags), the CasADi version and the schema. Two
  builds with the same key are the same library, so a rebuild that reproduces a key reuses the
  library without running the compiler. Nothing asks the compiler for its banner: a prebuilt
  library loads with no compiler on the PATH.
- the **source fingerprint** answers "was this library built from the model source in this
  tree?" without running SymPy: a hash of the syntax trees (comments, docstrings and layout
  dropped) of codegen/ and this contract package. The manifest lists every fingerprint whose
  build reproduced its key. A fingerprint the manifest does not list (a changed expression, a
  changed option) sends the runtime to the builder; a comment-only edit keeps the fingerprint.
"""
from __future__ import annotations

import ast
import functools
import hashlib
import importlib.util
import json
import os
from pathlib import Path

SCHEMA_VERSION = 2
CONTRACT_DIR = Path(__file__).resolve().parent
MANIFEST = "manifest.json"
GENERATED_ENV = "PUMPSIM_GENERATED"


def generated_dir() -> Path:
    """Where compiled kernels live: $PUMPSIM_GENERATED if set; in a source checkout its
    generated/; for an installed package the per-user cache (~/.cache/pumpsim/kernels on Linux),
    never site-packages."""
    if os.environ.get(GENERATED_ENV):
        return Path(os.environ[GENERATED_ENV])
    from pumpsim import CHECKOUT

    if CHECKOUT is not None:
        return CHECKOUT / "generated"
    from platformdirs import user_cache_dir

    return Path(user_cache_dir("pumpsim", appauthor=False)) / "kernels"


def library_name(structure) -> str:
    return f"pumpsim_{structure.variant.replace('-', '_')}"


def variant_dir(structure, key: str) -> Path:
    return generated_dir() / f"{structure.variant}-{key}"


def content_key(c_source_sha256: str, casadi_version: str, options: dict) -> str:
    """The cache key: what the library is made of (see the module docstring)."""
    payload = json.dumps({"schema": SCHEMA_VERSION, "c_source": c_source_sha256,
                          "casadi": casadi_version, "options": options}, sort_keys=True)
    return hashlib.sha256(payload.encode()).hexdigest()[:20]


def codegen_dir() -> Path | None:
    """The folder of pumpsim.codegen (a checkout's codegen/ or the installed subpackage), found
    without importing it (None when absent)."""
    spec = importlib.util.find_spec("pumpsim.codegen")
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(list(spec.submodule_search_locations)[0])


def _strip_docstrings(tree: ast.AST) -> ast.AST:
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                and body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)):
            node.body = body[1:] or [ast.Pass()]
    return tree


def file_fingerprint(text: str) -> str:
    """Hash of a Python source's syntax tree: comments, docstrings and layout do not count."""
    tree = _strip_docstrings(ast.parse(text))
    return hashlib.sha256(ast.dump(tree, include_attributes=False).encode()).hexdigest()


@functools.lru_cache(maxsize=8)
def _fingerprint_of(folders: tuple) -> str:
    h = hashlib.sha256()
    for folder in folders:
        for path in sorted(Path(folder).glob("*.py")):
            h.update(f"{Path(folder).name}/{path.name}".encode())
            h.update(file_fingerprint(path.read_text()).encode())
    return h.hexdigest()[:20]


def source_fingerprint(folders=None) -> str | None:
    """Fingerprint of the model source (codegen/ and this contract); None without codegen/."""
    if folders is None:
        cg = codegen_dir()
        if cg is None:
            return None
        folders = (cg, CONTRACT_DIR)
    return _fingerprint_of(tuple(str(f) for f in folders))


def read_manifest(folder: Path) -> dict | None:
    try:
        return json.loads((Path(folder) / MANIFEST).read_text())
    except (OSError, ValueError):
        return None


def trusted_manifest(folder: Path, variant: str, casadi_version: str, fingerprint: str | None,
                     check_fingerprint: bool = True) -> dict | None:
    """The manifest of `folder` if its library may be loaded for this tree, else None: same
    variant, schema and CasADi, a key that matches its recorded contents, the library's bytes as
    recorded and (when checked and known) this tree's source fingerprint among those it lists."""
    m = read_manifest(folder)
    if not m or m.get("schema") != SCHEMA_VERSION or m.get("variant") != variant:
        return None
    if m.get("casadi") != casadi_version:
        return None
    if m.get("key") != content_key(m.get("c_source_sha256", ""), m["casadi"], m.get("options", {})):
        return None
    if check_fingerprint and fingerprint is not None and fingerprint not in m.get("source_fingerprints", []):
        return None
    lib = Path(folder) / m.get("library", "")
    if not lib.is_file() or hashlib.sha256(lib.read_bytes()).hexdigest() != m.get("library_sha256"):
        return None
    return m


def find_variant(structure, casadi_version: str, fingerprint: str | None):
    """(folder, manifest) of a trusted build of `structure` in generated_dir(), or (None, None)."""
    base = generated_dir()
    for folder in sorted(base.glob(f"{structure.variant}-*")):
        m = trusted_manifest(folder, structure.variant, casadi_version, fingerprint)
        if m is not None:
            return folder, m
    return None, None


def umask_mode(directory: bool = False) -> int:
    """The mode a new file (0666) or folder (0777) gets under the current umask (a build folder made
    by mkdtemp is 0700 and would hide the kernels from colleagues sharing generated/)."""
    mask = os.umask(0)
    os.umask(mask)
    return (0o777 if directory else 0o666) & ~mask


def write_manifest(folder: Path, manifest: dict) -> None:
    """Atomic replace (a reader never sees half a manifest)."""
    tmp = Path(folder) / f".{MANIFEST}.{os.getpid()}"
    tmp.write_text(json.dumps(manifest, indent=1))
    os.replace(tmp, Path(folder) / MANIFEST)
