"""Every name a package of imucal lists in ``__all__`` (its lazy stub, SPEC 1) resolves: a stub
that names a function moved elsewhere fails only on first use, so it is checked here."""

from __future__ import annotations

import importlib
import pkgutil

import pytest

import imucal

PACKAGES = ["imucal"] + [
    m.name for m in pkgutil.walk_packages(imucal.__path__, "imucal.") if m.ispkg
]


@pytest.mark.parametrize("package", PACKAGES)
def test_every_listed_name_resolves(package):
    module = importlib.import_module(package)
    missing = []
    for name in getattr(module, "__all__", []):
        try:
            getattr(module, name)
        except (AttributeError, ImportError) as err:
            missing.append(f"{name}: {err}")
    assert not missing, f"{package} lists names that do not resolve: {missing}"
