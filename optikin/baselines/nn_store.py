"""Saving and loading trained networks together with what they were trained on.

A store is a folder with two files, neither of them a pickle:

``metadata.json``
    the CBHA geometry (radii, Table I limits, sections), the database settings
    (seed, candidates, ranges, coupling, split), the software versions that
    wrote it (optikin, scikit-learn, numpy, python; for information only), and
    per model its task (key, title, input and output columns), training setting,
    eq. (11) penalty, chosen width, validation criterion and best epoch per width,
    test MSE and training time; plus the SHA-256 of ``weights.npz``.
``weights.npz``
    per model (prefix ``<task key>.``): ``coef0``, ``coef1``, ... and
    ``intercept0``, ... (the layers of its
    :class:`~optikin.baselines.nn_models.Network`), ``activation`` (a string
    array), the affine maps ``x_offset``, ``x_scale``, ``y_offset``, ``y_scale``,
    and the width search: ``search_widths``, ``search_values``, ``search_epochs``.
    Plain numeric and string arrays, read with ``allow_pickle=False``.

The weights are evaluated by :func:`~optikin.baselines.nn_models.forward_pass`,
not by scikit-learn, so a store written with one scikit-learn version loads in
any other (and can ship with the package).

:func:`load_models` reads the metadata first and raises
:class:`~optikin.errors.InputDataError`, naming the store and the field, when
the models do not belong to the problem: another geometry or Table I, another
database (its test split would differ, and could overlap the models' training
rows), another training setting or penalty, a missing model, or a
``weights.npz`` whose checksum differs or whose arrays are missing or do not fit
together. The checksum detects damage, not tampering; loading runs no code from
the files.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import platform
import shutil
import tempfile
import zipfile
from dataclasses import asdict
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from optikin import __version__
from optikin.arms.cbha import CBHAGeometry
from optikin.baselines.nn_database import DatabaseSpec, LearningDatabase
from optikin.baselines.nn_models import Network, Task, TrainedModel, TrainingSetting, split_mse
from optikin.errors import InputDataError

FORMAT = "optikin-nn-models"
FORMAT_VERSION = 2
METADATA, WEIGHTS = "metadata.json", "weights.npz"
MAPS = ("x_offset", "x_scale", "y_offset", "y_scale")


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def describe_model(model: TrainedModel, db: LearningDatabase) -> dict[str, Any]:
    """Everything about one model except its arrays (those are in ``weights.npz``)."""
    task = model.task
    return {
        "task": task.key,
        "title": task.title,
        "inputs": [task.inputs[0], list(task.inputs[1])],
        "outputs": [task.outputs[0], list(task.outputs[1])],
        "penalised": task.penalised,
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
        "versions": {
            "optikin": __version__,
            "scikit-learn": metadata.version("scikit-learn"),
            "numpy": np.__version__,
            "python": platform.python_version(),
        },
        "geometry": asdict(db.geometry),
        "database": db.spec.as_dict(),
        "database rows": {"train": len(db.train), "validation": len(db.validation), "test": len(db.test)},
        "models": [describe_model(m, db) for m in models],
    }


def model_arrays(model: TrainedModel) -> dict[str, np.ndarray]:
    """The arrays of one model in ``weights.npz``, keyed ``<task key>.<name>``."""
    net, key = model.network, model.task.key
    widths = sorted(model.search)
    arrays = {f"coef{i}": W for i, W in enumerate(net.coefs)}
    arrays |= {f"intercept{i}": b for i, b in enumerate(net.intercepts)}
    arrays |= {"activation": np.array(net.activation)}
    arrays |= {name: np.asarray(getattr(model, name), dtype=float) for name in MAPS}
    arrays |= {
        "search_widths": np.array(widths, dtype=np.int64),
        "search_values": np.array([model.search[n] for n in widths], dtype=float),
        "search_epochs": np.array([model.epochs[n] for n in widths], dtype=np.int64),
    }
    return {f"{key}.{name}": a for name, a in arrays.items()}


def save_models(path: str | Path, models: list[TrainedModel], db: LearningDatabase) -> Path:
    """Write ``models`` (trained on ``db``) to the folder ``path``, replacing it atomically."""
    path = Path(path)
    keys = [m.task.key for m in models]
    if len(set(keys)) != len(keys):
        raise ValueError(f"two models of the same task in {keys}")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        arrays: dict[str, Any] = {k: a for m in models for k, a in model_arrays(m).items()}
        with open(tmp / WEIGHTS, "wb") as fh:
            np.savez_compressed(fh, **arrays)
        metadata = store_metadata(models, db) | {"sha256": _sha256(tmp / WEIGHTS)}
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
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputDataError(f"cannot read {METADATA}: {exc}", source=source) from None
    if not isinstance(metadata, dict) or metadata.get("format") != FORMAT:
        raise InputDataError(f"not a {FORMAT} store", source=source, field="format")
    if metadata.get("format_version") != FORMAT_VERSION:
        raise InputDataError(
            f"format version {metadata.get('format_version')!r}, this optikin reads "
            f"{FORMAT_VERSION}; retrain (delete the store)",
            source=source,
            field="format_version",
        )
    return metadata


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return math.isclose(a, b, rel_tol=1e-12, abs_tol=0.0)
    return a == b


def _check_section(stored: Any, expected: dict, section: str, source: str) -> None:
    if not isinstance(stored, dict):
        raise InputDataError(f"missing or not a mapping; the problem has {expected!r}", source=source, field=section)
    for key, value in expected.items():
        if key not in stored:
            raise InputDataError(f"missing; the problem has {value!r}", source=source, field=f"{section}.{key}")
        if not _same(stored[key], value):
            raise InputDataError(
                f"models were trained with {stored[key]!r}, the problem has {value!r}",
                source=source,
                field=f"{section}.{key}",
            )


def _rebuild(described: dict[str, Any], weights: Any, source: str) -> TrainedModel:
    """The :class:`TrainedModel` of one metadata entry and its arrays."""
    key = described["task"]
    field = f"models.{key}"

    def array(name: str) -> np.ndarray:
        try:
            return weights[f"{key}.{name}"]
        except KeyError:
            raise InputDataError(
                f"{WEIGHTS} has no array {key}.{name}", source=source, field=f"{field}.{name}"
            ) from None
        except ValueError as exc:  # an object array, which would need pickle
            raise InputDataError(f"{WEIGHTS}: {key}.{name}: {exc}", source=source, field=f"{field}.{name}") from None

    layers = sum(1 for name in weights.files if name.startswith(f"{key}.coef"))
    try:
        network = Network(
            tuple(array(f"coef{i}") for i in range(layers)),
            tuple(array(f"intercept{i}") for i in range(layers)),
            str(array("activation")),
        )
    except ValueError as exc:
        raise InputDataError(f"{WEIGHTS}: {exc}", source=source, field=f"{field}.network") from None
    maps = {name: array(name) for name in MAPS}
    sizes = {
        "x_offset": network.coefs[0].shape[0],
        "x_scale": network.coefs[0].shape[0],
        "y_offset": network.coefs[-1].shape[1],
        "y_scale": network.coefs[-1].shape[1],
    }
    for name, size in sizes.items():
        if maps[name].shape != (size,):
            raise InputDataError(
                f"shape {maps[name].shape}, the network needs ({size},)", source=source, field=f"{field}.{name}"
            )
    widths, values, epochs = array("search_widths"), array("search_values"), array("search_epochs")
    if not widths.shape == values.shape == epochs.shape:
        raise InputDataError(
            "search_widths, search_values and search_epochs differ in length", source=source, field=f"{field}.search"
        )
    try:
        task = Task(
            key,
            described["title"],
            (described["inputs"][0], tuple(described["inputs"][1])),
            (described["outputs"][0], tuple(described["outputs"][1])),
            bool(described["penalised"]),
        )
        setting = TrainingSetting(**described["setting"])
        neurons, penalty = int(described["neurons"]), float(described["penalty"])
        training_time = float(described["training time [s]"])
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise InputDataError(f"incomplete description: {exc!r}", source=source, field=field) from None
    if (len(task.inputs[1]), len(task.outputs[1])) != (sizes["x_offset"], sizes["y_offset"]):
        raise InputDataError(
            f"the network maps {sizes['x_offset']} to {sizes['y_offset']} values, the task "
            f"{len(task.inputs[1])} to {len(task.outputs[1])}",
            source=source,
            field=f"{field}.inputs",
        )
    if network.hidden_layer_sizes[:1] != (neurons,):
        raise InputDataError(
            f"the network has hidden layers {network.hidden_layer_sizes}, the metadata {neurons} neurons",
            source=source,
            field=f"{field}.neurons",
        )
    return TrainedModel(
        task=task,
        setting=setting,
        penalty=penalty,
        neurons=neurons,
        network=network,
        **maps,
        search={int(n): float(v) for n, v in zip(widths, values)},
        epochs={int(n): int(e) for n, e in zip(widths, epochs)},
        training_time=training_time,
    )


def load_models(
    path: str | Path, geometry: CBHAGeometry, spec: DatabaseSpec, required: dict[str, tuple[TrainingSetting, float]]
) -> list[TrainedModel]:
    """The models of the store ``path`` for the tasks in ``required`` (task key -> (setting, penalty)).

    Raises :class:`InputDataError` naming the store and the field when anything differs from
    the problem (module docstring).
    """
    path = Path(path)
    source = str(path)
    metadata = read_metadata(path)
    _check_section(metadata.get("geometry"), json.loads(json.dumps(asdict(geometry))), "geometry", source)
    _check_section(metadata.get("database"), json.loads(json.dumps(spec.as_dict())), "database", source)
    entries = metadata.get("models")
    if not isinstance(entries, list) or not all(isinstance(m, dict) and "task" in m for m in entries):
        raise InputDataError("not a list of model descriptions", source=source, field="models")
    described = {m["task"]: m for m in entries}
    for key, (setting, penalty) in required.items():
        if key not in described:
            raise InputDataError(
                f"no model {key!r}; the store holds {', '.join(described) or 'none'}", source=source, field="models"
            )
        _check_section(
            described[key].get("setting"), json.loads(json.dumps(asdict(setting))), f"models.{key}.setting", source
        )
        if not _same(described[key].get("penalty"), float(penalty)):
            raise InputDataError(
                f"trained with penalty {described[key].get('penalty')}, the problem asks for {penalty}",
                source=source,
                field=f"models.{key}.penalty",
            )
    try:
        data = (path / WEIGHTS).read_bytes()
    except OSError as exc:
        raise InputDataError(f"cannot read {WEIGHTS}: {exc.strerror or exc}", source=source, field=WEIGHTS) from None
    if hashlib.sha256(data).hexdigest() != metadata.get("sha256"):
        raise InputDataError(
            f"{WEIGHTS} differs from the checksum in {METADATA} (changed or damaged)", source=source, field="sha256"
        )
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as weights:
            return [_rebuild(described[key], weights, source) for key in required]
    except (OSError, zipfile.BadZipFile, EOFError) as exc:
        raise InputDataError(f"cannot read {WEIGHTS}: {exc}", source=source, field=WEIGHTS) from None
