"""`pumpsim example NAME DIR`: copy a bundled example (config, measurements, studies)."""
from __future__ import annotations

from .common import Help


def register(sub):
    e = sub.add_parser("example", help="copy a bundled example (config, measurements, studies) into a folder",
                       formatter_class=Help,
                       description="Copy a bundled configuration, its simulated measurements (DIR/data/) and "
                       "its studies (DIR/studies/) into DIR; `pumpsim example test_rig examples` makes the "
                       "documentation's paths (examples/...) work.")
    e.add_argument("name", nargs="?", help="example name (see --list)")
    e.add_argument("dir", nargs="?", help="destination folder (created if missing)")
    e.add_argument("--list", action="store_true", help="list the bundled examples and their files")
    e.set_defaults(func=run)


def run(a) -> int:
    from .. import bundled
    from ..errors import ConfigError

    if a.list:
        for name in bundled.names():
            print(f"{name}: {bundled.description(name)}\n    {', '.join(bundled.files(name))}")
        return 0
    if not a.name or not a.dir:
        raise ConfigError("give an example NAME and a folder DIR (`pumpsim example test_rig examples`), "
                          "or --list")
    for path in bundled.copy_example(a.name, a.dir):
        print(path)
    return 0
