"""File formats: CSV records, atomic writes with the user's permissions (only ever replacing a regular
file; links written through), a lock for an output folder, standard JSON."""

from ._csv import MAX_COLUMNS as MAX_COLUMNS
from ._csv import json_bytes as json_bytes
from ._csv import json_safe as json_safe
from ._csv import non_finite_paths as non_finite_paths
from ._csv import read_csv_columns as read_csv_columns
from ._csv import write_csv_columns as write_csv_columns
from ._files import FOLDER_LOCK_NAME as FOLDER_LOCK_NAME
from ._files import atomic_write_bytes as atomic_write_bytes
from ._files import check_output_file as check_output_file
from ._files import current_umask as current_umask
from ._files import folder_lock as folder_lock
from ._files import make_temp_dir as make_temp_dir
from ._files import output_target as output_target

__all__ = ["FOLDER_LOCK_NAME", "MAX_COLUMNS", "atomic_write_bytes", "check_output_file", "current_umask", "folder_lock", "json_bytes",
           "json_safe", "make_temp_dir", "non_finite_paths", "output_target", "read_csv_columns", "write_csv_columns"]
