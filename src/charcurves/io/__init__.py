"""File formats: CSV records, atomic writes with the user's permissions, standard JSON."""

from ._csv import atomic_write_bytes as atomic_write_bytes
from ._csv import current_umask as current_umask
from ._csv import json_bytes as json_bytes
from ._csv import json_safe as json_safe
from ._csv import make_temp_dir as make_temp_dir
from ._csv import non_finite_paths as non_finite_paths
from ._csv import read_csv_columns as read_csv_columns
from ._csv import write_csv_columns as write_csv_columns

__all__ = ["atomic_write_bytes", "current_umask", "json_bytes", "json_safe", "make_temp_dir", "non_finite_paths",
           "read_csv_columns", "write_csv_columns"]
