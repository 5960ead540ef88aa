"""Users' own models: from an MJCF file, a Python file, or an installed package.

- ``.xml``: an MJCF file, compiled by MuJoCo and turned into a reference Model in its own joint
  coordinates (reference.mjcf.loader; what is supported: docs/user_models.md).
- ``.py``: a Python file that defines a function ``models()`` returning a Model or a list of
  Models built with the public API (reference.system, reference.forces). The file is run as a
  module of its own; nothing else in it is called.
- the entry-point group ``crosscheck.models``: a package declares, in its pyproject.toml,
  ``[project.entry-points."crosscheck.models"] name = "package.module:function"``, where the
  function is a ``models()`` hook as above.

Every failure is one line (reference.errors.ModelFileError): malformed XML, a file MuJoCo
rejects (its message passed on), an element the reference cannot represent, a Python file that
raises or defines no models, a name used twice.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from reference.errors import ModelFileError, ModelInputError
from reference.mjcf.loader import MjcfImport, import_mjcf
from reference.system import Model

ENTRY_POINT_GROUP = "crosscheck.models"
HOOK = "models"


@dataclass(frozen=True)
class UserModel:
    """A model from outside the built-in registry and where it came from."""

    model: Model
    origin: str  # e.g. "fourbar.xml (MJCF)", "mech.py:models()", "entry point crosscheck.models:x"
    kind: str  # "mjcf", "python" or "entry-point"
    mjcf: MjcfImport | None = None  # the MJCF import (state maps, compiled model), if any

    @property
    def name(self) -> str:
        return self.model.name


def _as_models(result, where: str) -> list[Model]:
    """A hook's return value as a list of validated Models."""
    items = [result] if isinstance(result, Model) else result
    try:
        items = list(items)
    except TypeError:
        raise ModelFileError(
            f"{where}: {HOOK}() returned {type(result).__name__}, expected a "
            f"Model or a list of Models"
        ) from None
    if not items:
        raise ModelFileError(f"{where}: {HOOK}() returned no models")
    bad = [type(x).__name__ for x in items if not isinstance(x, Model)]
    if bad:
        raise ModelFileError(
            f"{where}: {HOOK}() returned {', '.join(bad)}, expected reference.system.Model objects"
        )
    for mdl in items:
        if not mdl.coordinates:  # every check would compare empty arrays
            raise ModelFileError(
                f"{where}: model {mdl.name!r} has no coordinates (no moving body), so it has "
                "no equations of motion to check; give it a coordinate and its speed"
            )
        try:
            mdl.validate()
        except ModelInputError as exc:
            raise ModelFileError(f"{where}: {exc}") from exc
    return items


def _load_python(path: Path) -> list[UserModel]:
    tag = hashlib.sha256(str(path.resolve()).encode()).hexdigest()[:10]
    mod_name = f"crosscheck_user_{_safe(path.stem)}_{tag}"
    spec = importlib.util.spec_from_file_location(mod_name, path)
    if spec is None or spec.loader is None:
        raise ModelFileError(f"{path}: cannot be imported as a Python file")
    module = importlib.util.module_from_spec(spec)
    sys.modules[mod_name] = module  # dataclasses and pickling need the module registered
    try:
        spec.loader.exec_module(module)
    except SystemExit as exc:  # sys.exit() at import would end the command with its code
        sys.modules.pop(mod_name, None)
        raise ModelFileError(
            f"{path}: called sys.exit({exc.code!r}) while loading, so it defines no models; "
            f"keep a model file free of code that exits (put it under "
            f'`if __name__ == "__main__":`)'
        ) from None
    except Exception as exc:  # the user's code: report it in one line, whatever it raised
        sys.modules.pop(mod_name, None)
        raise ModelFileError(f"{path}: raised {type(exc).__name__} while loading: {exc}") from exc
    hook = getattr(module, HOOK, None)
    if not callable(hook):
        raise ModelFileError(
            f"{path}: defines no {HOOK}() function; add one that returns the "
            f"file's Model objects (docs/user_models.md)"
        )
    try:
        result = hook()
    except SystemExit as exc:
        raise ModelFileError(
            f"{path}: {HOOK}() called sys.exit({exc.code!r}); it must return the file's models"
        ) from None
    except Exception as exc:
        raise ModelFileError(f"{path}: {HOOK}() raised {type(exc).__name__}: {exc}") from exc
    return [
        UserModel(mdl, f"{path.name}:{HOOK}()", "python") for mdl in _as_models(result, str(path))
    ]


def _safe(s: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in s)


def load_model_file(path, *, project: bool = False, ctrl=None) -> list[UserModel]:
    """The models a file defines, each with its origin: an MJCF file (.xml) gives one, a
    Python file (.py) what its models() hook returns.

    Parameters
    ----------
    path : str or Path
        The file.
    project : bool
        An MJCF initial state off the constraint manifold is projected onto it (else refused);
        see reference.mjcf.loader.import_mjcf.
    ctrl : mapping of str to float, optional
        MJCF actuator controls by name (the others: keyframe 0's, or 0); a name the file has
        no actuator of is refused.

    Returns
    -------
    list of UserModel
    """
    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix in (".xml", ".mjcf"):
        imp = import_mjcf(path, project=project, ctrl=ctrl)
        return [UserModel(imp.model, f"{path.name} (MJCF)", "mjcf", imp)]
    if suffix == ".py":
        return _load_python(path)
    raise ModelFileError(
        f"{path}: unknown model file type {suffix!r}; give an MJCF file "
        f"(.xml) or a Python file (.py) with a {HOOK}() function"
    )


def _controls_by_file(paths: list[Path], ctrl: Mapping[str, float]) -> list[dict[str, float]]:
    """Each MJCF file's share of the --ctrl controls (the names of its actuators); a name no
    file has an actuator of is refused, naming the files' actuators."""
    from reference.mjcf.actuators import actuator_name
    from reference.mjcf.loader import compile_file

    shares, seen = [], set()
    for p in paths:
        if p.suffix.lower() not in (".xml", ".mjcf") or not ctrl:
            shares.append({})
            continue
        m = compile_file(p)
        names = {actuator_name(m, a) for a in range(m.nu)}
        seen |= names
        shares.append({k: v for k, v in ctrl.items() if k in names})
    unknown = sorted(set(ctrl) - seen)
    if unknown:
        listed = ", ".join(sorted(seen)) if seen else "none"
        raise ModelFileError(
            f"--ctrl {', '.join(unknown)}: no actuator of that name in the model files "
            f"(their actuators: {listed})"
        )
    return shares


def entry_point_models(group: str = ENTRY_POINT_GROUP) -> list[UserModel]:
    """Models that installed packages add through the entry-point group `crosscheck.models`."""
    out = []
    for ep in metadata.entry_points(group=group):
        where = f"entry point {ep.name} ({ep.value})"
        try:
            hook = ep.load()
            result = hook() if callable(hook) else hook
        except SystemExit as exc:  # a package's sys.exit() would end the command unsaid
            raise ModelFileError(f"{where}: called sys.exit({exc.code!r})") from None
        except Exception as exc:
            raise ModelFileError(f"{where}: raised {type(exc).__name__}: {exc}") from exc
        out += [
            UserModel(mdl, f"entry point {group}:{ep.name}", "entry-point")
            for mdl in _as_models(result, where)
        ]
    return out


def load_all(
    paths: Iterable = (),
    *,
    entry_points: bool = True,
    builtin_names: Iterable[str] = (),
    project: bool = False,
    ctrl: Mapping[str, float] | None = None,
) -> list[UserModel]:
    """Models of every file in `paths` (in order) and of the entry points; a name given twice,
    or the name of a built-in model, is an error naming both origins. ``project`` and
    ``ctrl`` as load_model_file; each control goes to the files with an actuator of that name,
    and a name none has is refused."""
    found: list[UserModel] = []
    paths = [Path(p) for p in paths]
    for p in paths:
        if not p.is_file():
            raise ModelFileError(f"{p}: no such file")
    for p, share in zip(paths, _controls_by_file(paths, dict(ctrl or {})), strict=True):
        found += load_model_file(p, project=project, ctrl=share)
    if entry_points:
        found += entry_point_models()
    seen: dict[str, str] = {n: "the built-in models" for n in builtin_names}
    for um in found:
        if um.name in seen:
            raise ModelFileError(
                f"model name {um.name!r} from {um.origin} is already used by "
                f"{seen[um.name]}; rename it (Model(name=...))"
            )
        seen[um.name] = um.origin
    return found


def describe(um: UserModel) -> dict:
    """One row for `crosscheck models`: the model's shape and where it came from."""
    mdl = um.model
    return {
        "name": mdl.name,
        "origin": um.origin,
        "kind": um.kind,
        "title": mdl.title,
        "coordinates": [s.name for s in mdl.coordinates],
        "speeds": [s.name for s in mdl.speeds],
        "parameters": [p.name for p in mdl.parameters],
        "constraints": list(mdl.constraint_names),
        "formulations": list(mdl.formulations),
        "notes": mdl.geometry_note,
    }


def register_all(found: Iterable[UserModel]) -> list[str]:
    """Register loaded models with reference.models (get, origin, user_source) and return
    their names: what a command does with --model-file before resolving model names."""
    from reference import models

    names = []
    for um in found:
        models.register(um.model, um.origin, um.mjcf)
        names.append(um.name)
    return names
