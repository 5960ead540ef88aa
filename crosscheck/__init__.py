"""Textbook multiplier formulations cross-checked against the registered engines (Pinocchio,
MuJoCo, Exudyn, OpenSim).

``crosscheck.check`` and ``crosscheck.assert_passes`` (crosscheck.api) check a model from a
test suite; they load on first use, so importing the package (the CLI) stays light.
"""

__all__ = ["assert_passes", "check"]


def __getattr__(name):
    if name in __all__:
        from crosscheck import api

        return getattr(api, name)
    raise AttributeError(f"module 'crosscheck' has no attribute {name!r}")
