"""Saving and loading trained networks together with what they were trained on.

A store is a folder with two files:

``metadata.json``
    the CBHA geometry (radii, Table I limits, sections), the database settings
    (seed, candidates, ranges, coupling, split), the software versions
    (optikin, scikit-learn, numpy), and per model its task, training setting,
    eq. (11) penalty, chosen width, validation criterion per width, test MSE and
    training time; plus the SHA-256 of ``models.pkl``.
``models.pkl``
    the :class:`~optikin.baselines.nn_models.TrainedModel` objects, pickled.

:func:`load_models` reads the metadata first and raises
:class:`~optikin.errors.InputDataError`, naming the store and the field, when
the models do not belong to the problem: another geometry or Table I, another
database (its test split would differ, and could overlap the models' training
rows), another training setting or penalty, a missing model, another
scikit-learn version (pickled estimators are only guaranteed to load in the
version that wrote them), or a ``models.pkl`` whose checksum differs.
Unpickling runs code from the file: load only stores you made; the checksum
detects damage, not tampering.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import pickle
import platform
import shutil
import tempfile
from dataclasses import asdict
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
import sklearn

from optikin import __version__
from optikin.arms.cbha import CBHAGeometry
from optikin.baselines.nn_database import DatabaseSpec, LearningDatabase
from optikin.baselines.nn_models import TrainedModel, TrainingSetting, split_mse
from optikin.errors import InputDataError

FORMAT = "optikin-nn-models"
FORMAT_VERSION = 1
METADATA, MODELS = "metadata.json", "models.pkl"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def describe_model(model: TrainedModel, db: LearningDatabase) -> dict[str, Any]:
    """Everything about one model that a reader needs without unpickling it."""
    return {
        "task": model.task.key,
        "title": model.task.title,
        "setting": asdict(model.setting),
        "penalty": model.penalty,
        "neurons": model.neurons,
        "validation criterion per width": {str(n): v for n, v in model.search.items()},
        "best epoch per width": {str(n): e for n, e in model.epochs.items()},
        "test MSE": split_mse(model, db, "test"),
        "training time [s]": model.training_time,
    }


def store_metadata(models: list[TrainedModel], db: LearningDatabase) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "versions": {"optikin": __version__, "scikit-learn": sklearn.__version__, "numpy": np.__version__,
                     "python": platform.python_version()},
        "geometry": asdict(db.geometry),
        "database": db.spec.as_dict(),
        "database rows": {"train": len(db.train), "validation": len(db.validation), "test": len(db.test)},
        "models": [describe_model(m, db) for m in models],
    }


def save_models(path: str | Path, models: list[TrainedModel], db: LearningDatabase) -> Path:
    """Write ``models`` (trained on ``db``) to the folder ``path``, replacing it atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        with open(tmp / MODELS, "wb") as fh:
            pickle.dump(models, fh, protocol=pickle.HIGHEST_PROTOCOL)
        metadata = store_metadata(models, db) | {"sha256": _sha256(tmp / MODELS)}
        (tmp / METADATA).write_text(json.dumps(metadata, indent=2))
        if path.exists():
            old = path.with_name(f".{path.name}.old")
            shutil.rmtree(old, ignore_errors=True)
            os.replace(path, old)
            os.replace(tmp, path)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return path


def read_metadata(path: str | Path) -> dict[str, Any]:
    """The metadata of a store, or :class:`InputDataError` naming what is wrong with it."""
    path = Path(path)
    source = str(path)
    try:
        metadata = json.loads((path / METADATA).read_text())
    except FileNotFoundError:
        raise InputDataError(f"no {METADATA}: not a model store", source=source) from None
    except (OSError, json.JSONDecodeError) as exc:
        raise InputDataError(f"cannot read {METADATA}: {exc}", source=source) from None
    if not isinstance(metadata, dict) or metadata.get("format") != FORMAT:
        raise InputDataError(f"not a {FORMAT} store", source=source, field="format")
    if metadata.get("format_version") != FORMAT_VERSION:
        raise InputDataError(f"format version {metadata.get('format_version')!r}, this optikin reads "
                             f"{FORMAT_VERSION}", source=source, field="format_version")
    return metadata


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return math.isclose(a, b, rel_tol=1e-12, abs_tol=0.0)
    return a == b


def _check_section(stored: dict, expected: dict, section: str, source: str) -> None:
    for key, value in expected.items():
        if key not in stored:
            raise InputDataError(f"missing; the problem has {value!r}", source=source, field=f"{section}.{key}")
        if not _same(stored[key], value):
            raise InputDataError(f"models were trained with {stored[key]!r}, the problem has {value!r}",
                                 source=source, field=f"{section}.{key}")


def load_models(path: str | Path, geometry: CBHAGeometry, spec: DatabaseSpec,
                required: dict[str, tuple[TrainingSetting, float]]) -> list[TrainedModel]:
    """The models of the store ``path`` for the tasks in ``required`` (task key -> (setting, penalty)).

    Raises :class:`InputDataError` naming the store and the field when anything differs from
    the problem (module docstring).
    """
    path = Path(path)
    source = str(path)
    metadata = read_metadata(path)
    stored_sklearn = metadata.get("versions", {}).get("scikit-learn")
    if stored_sklearn != sklearn.__version__:
        raise InputDataError(f"written by scikit-learn {stored_sklearn}, this is {sklearn.__version__}; "
                             "retrain (delete the store)", source=source, field="versions.scikit-learn")
    _check_section(metadata.get("geometry", {}), json.loads(json.dumps(asdict(geometry))), "geometry", source)
    _check_section(metadata.get("database", {}), json.loads(json.dumps(spec.as_dict())), "database", source)
    described = {m["task"]: m for m in metadata.get("models", [])}
    for key, (setting, penalty) in required.items():
        if key not in described:
            raise InputDataError(f"no model {key!r}; the store holds {', '.join(described) or 'none'}",
                                 source=source, field="models")
        _check_section(described[key]["setting"], json.loads(json.dumps(asdict(setting))),
                       f"models.{key}.setting", source)
        if not _same(described[key]["penalty"], float(penalty)):
            raise InputDataError(f"trained with penalty {described[key]['penalty']}, the problem asks for {penalty}",
                                 source=source, field=f"models.{key}.penalty")
    pickled = path / MODELS
    try:
        digest = _sha256(pickled)
    except OSError as exc:
        raise InputDataError(f"cannot read {MODELS}: {exc.strerror or exc}", source=source) from None
    if digest != metadata.get("sha256"):
        raise InputDataError(f"{MODELS} differs from the checksum in {METADATA} (changed or damaged)",
                             source=source, field="sha256")
    with open(pickled, "rb") as fh:
        models = pickle.load(fh)
    by_key = {m.task.key: m for m in models}
    return [by_key[key] for key in required]
