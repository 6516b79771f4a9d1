"""Package discovery: the library under ``mpfem_fenicsx/``, and the design card's top-level
``forms/`` (the UFL forms) and ``meshes/`` (particle and assembly meshes, packings) mapped in as
``mpfem_fenicsx.forms`` and ``mpfem_fenicsx.meshes``. Everything else is in pyproject.toml."""

from setuptools import find_packages, setup

#: top-level folders installed as subpackages of the library
MAPPED = {"mpfem_fenicsx.forms": "forms", "mpfem_fenicsx.meshes": "meshes"}

packages = find_packages(include=["mpfem_fenicsx", "mpfem_fenicsx.*"])
for name, folder in MAPPED.items():
    packages += [name] + [f"{name}.{sub}" for sub in find_packages(folder)]
setup(packages=packages, package_dir=dict(MAPPED))
