"""The bundled EVP example's swept volume as its comment and the documentation quote it: N (V_max - V_min)
of one cell over a revolution, from the compiled cell geometry (spec §8)."""
import re

import numpy as np
import pytest

from pumpsim.kernels.pneumatic import kernels, parameter_vector
from tests.conftest import EXAMPLES, ROOT
from tests.pneumatic_helpers import evp_config
from tests.tolerances import QUOTED_FIGURE_REL


def _swept_cm3():
    cfg = evp_config()
    k, p = kernels(cfg), parameter_vector(cfg)
    V = [float(k["cell_geometry"](th, p)[0][0]) for th in np.linspace(0, 2 * np.pi, 721)]
    return cfg.vanes * (max(V) - min(V)) * 1e6


@pytest.mark.parametrize("path,pattern", [
    (EXAMPLES / "evp_booster.toml", r"~(\d+(?:\.\d+)?) cm\^3/rev"),
    (ROOT / "docs" / "getting-started.md", r"25 mm wide: ~(\d+(?:\.\d+)?) cm³/rev"),
])
def test_quoted_swept_volume_is_the_models(path, pattern):
    quoted = float(re.search(pattern, path.read_text(encoding="utf-8")).group(1))
    assert quoted == pytest.approx(_swept_cm3(), rel=QUOTED_FIGURE_REL)
