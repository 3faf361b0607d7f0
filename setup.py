"""Package discovery (metadata and layout are in pyproject.toml): every package under pumpsim/, and
the repository's codegen/ and examples/ folders installed as pumpsim.codegen and pumpsim.examples
(pyproject.toml's package-dir). pyproject.toml alone cannot discover packages and also rename two."""
from setuptools import find_packages, setup

setup(packages=[*find_packages(include=["pumpsim", "pumpsim.*"]), "pumpsim.codegen", "pumpsim.examples"])
