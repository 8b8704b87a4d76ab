"""Saved models on their way from a worker to the driver: the files of ``FittedModel.save`` as bytes.

A worker saves a model into its own temporary folder and returns the files' bytes with the rows;
the driver writes them under the output folder. On a cluster the workers' disks are not the
driver's, and the output folder belongs to the driver alone.
"""

from __future__ import annotations

import os
import shutil
import tempfile

__all__ = ["model_files", "write_model_files", "write_row_model", "MODEL_FILES_KEY"]

#: Key of a result row that carries the saved model's files (``{name: bytes}``) to the driver; the
#: driver removes it before the row is stored.
MODEL_FILES_KEY = "_model_files"


def model_files(model) -> dict[str, bytes]:
    """``{file name: bytes}`` of ``model.save`` (written in a temporary folder of this process)."""
    with tempfile.TemporaryDirectory(prefix="charcurves-model-") as tmp:
        path = os.path.join(tmp, "model")
        model.save(path)
        out = {}
        for name in sorted(os.listdir(path)):
            with open(os.path.join(path, name), "rb") as fh:
                out[name] = fh.read()
        return out


def write_model_files(path: str, files: dict[str, bytes]) -> None:
    """Write a model folder from :func:`model_files`: a new folder appears complete (written in a
    temporary sibling, then renamed); an existing one is overwritten file by file, ``model.json``
    (the commit point that :func:`charcurves.load_model` checks the arrays against) last."""
    from ..io import atomic_write_bytes, make_temp_dir

    order = sorted(files, key=lambda name: (name == "model.json", name))
    if os.path.islink(path):  # a link to a model folder is written through; the link stays
        path = os.path.realpath(path)
    parent = os.path.dirname(os.path.abspath(path))
    os.makedirs(parent, exist_ok=True)
    if not os.path.exists(path):
        tmp = make_temp_dir(parent, ".tmp-model-")
        try:
            for name in order:
                atomic_write_bytes(os.path.join(tmp, name), files[name])
            os.rename(tmp, path)
            return
        except OSError:
            if not os.path.isdir(path):  # not a concurrent writer's folder: a real failure
                raise
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    for name in order:
        atomic_write_bytes(os.path.join(path, name), files[name])


def write_row_model(row: dict, models_dir: str | None, store_dir: str) -> None:
    """Write the model files a worker returned with ``row`` (and drop them from it)."""
    files = row.pop(MODEL_FILES_KEY, None)
    name = (row.get("extra") or {}).pop("model_name", None)
    if files is None or models_dir is None or name is None:
        return
    path = os.path.join(models_dir, name)
    write_model_files(path, files)
    try:
        row["extra"]["model_path"] = os.path.relpath(os.path.abspath(path), store_dir).replace(os.sep, "/")
    except ValueError:  # another drive (Windows)
        row["extra"]["model_path"] = os.path.abspath(path)
