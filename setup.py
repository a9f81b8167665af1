"""What pyproject.toml cannot say: the state-machine models, kept in
``models/`` at the top of the repository, ship inside the package as
``malcolm/models`` (where ``malcolm.fsm.builtin_models_dir`` finds them in
an installed wheel). Everything else is in pyproject.toml."""

from setuptools import find_namespace_packages, setup

setup(
    packages=[*find_namespace_packages(include=["malcolm*"]), "malcolm.models"],
    package_dir={"malcolm.models": "models"},
    package_data={"malcolm.models": ["*.yaml"]},
)
