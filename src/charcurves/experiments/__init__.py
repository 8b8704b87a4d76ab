"""Experiments: noise sweeps, forward validation sets and a resumable results store.

Public API
----------
Sweep, paper_grid(), quick_grid()          what to run (systems × methods × SNR × realisations)
run_sweep(sweep, store_path, ...)          run what the store lacks (local processes or Ray)
ResultsStore(path)                         SQLite rows, completed_keys(), to_dataframe(), to_csv()
make_validation_cases(system, n, seed=)    random conditions whose true trajectory stays in the box
evaluate_forward(model, system, cases)     t_sep (ε = 0.2, censored) and RMSE[x] per case
run_benchmark(out_dir, ...)                the paper's study: sweeps, tables, figures, report.md/.html
build_report(out_dir)                      rebuild the report from results.csv, run.json, extras.json alone
docs_tables(results_root)                  the docs' headline tables from the committed results folders
fill_table_markers(text, tables)           write them between a page's <!-- table:NAME --> markers
zoo_coverage_tables(results_root)          docs/uncertainty-zoo.md's coverage tables; gated_rows, coverage_table, per_curve_table
selection_tables(results_root)             the parity test on the zoo, Duffing from three records, units; parity_table, units_table
ray_ensemble_fitter(address)               select_family's ensemble fits as Ray tasks on a cluster
run_real_benchmark(name, out_dir, ...)     a real benchmark (charcurves.datasets): fit, test RMSE after the window

Examples
--------
>>> from charcurves.experiments import Sweep, quick_grid
>>> sweep = Sweep(systems=["duffing"], methods=["parametric", "nn-cc"], **quick_grid())
>>> len(sweep.jobs())
12
"""

from ._benchmark import BENCHMARK_SECTIONS as BENCHMARK_SECTIONS
from ._benchmark import SYSTEMS as BENCHMARK_SYSTEMS
from ._benchmark import BenchmarkResult as BenchmarkResult
from ._benchmark import parse_name_list as parse_name_list
from ._benchmark import parse_snr_list as parse_snr_list
from ._benchmark import run_benchmark as run_benchmark
from ._docs_tables import docs_tables as docs_tables
from ._real import run_real_benchmark as run_real_benchmark
from ._docs_tables import fill_table_markers as fill_table_markers
from ._selection_tables import parity_table as parity_table
from ._selection_tables import selection_tables as selection_tables
from ._selection_tables import units_table as units_table
from ._zoo_coverage_tables import coverage_table as coverage_table
from ._zoo_coverage_tables import gated_rows as gated_rows
from ._zoo_coverage_tables import per_curve_table as per_curve_table
from ._zoo_coverage_tables import zoo_coverage_tables as zoo_coverage_tables
from ._report_inputs import build_report as build_report
from ._remote import ray_ensemble_fitter as ray_ensemble_fitter
from ._runner import Job as Job
from ._runner import RunSettings as RunSettings
from ._runner import run_unit as run_unit
from ._store import KEY_COLUMNS as KEY_COLUMNS
from ._store import VALUE_COLUMNS as VALUE_COLUMNS
from ._store import ResultsStore as ResultsStore
from ._store import job_key as job_key
from ._executors import SweepInterrupted as SweepInterrupted
from ._sweep import EXECUTORS as EXECUTORS
from ._sweep import PAPER_SNR_DB as PAPER_SNR_DB
from ._sweep import QUICK_SNR_DB as QUICK_SNR_DB
from ._sweep import Sweep as Sweep
from ._sweep import SweepReport as SweepReport
from ._sweep import dataset_seed as dataset_seed
from ._sweep import default_fit_options as default_fit_options
from ._sweep import paper_grid as paper_grid
from ._sweep import plan_units as plan_units
from ._sweep import quick_grid as quick_grid
from ._sweep import run_sweep as run_sweep
from ..metrics import HORIZONS as HORIZONS
from ..metrics import VALIDATION_RANGES as VALIDATION_RANGES
from ..metrics import CaseResult as CaseResult
from ..metrics import ForwardEvaluation as ForwardEvaluation
from ..metrics import ValidationCase as ValidationCase
from ..metrics import ValidationSet as ValidationSet
from ..metrics import cached_validation_cases as cached_validation_cases
from ..metrics import evaluate_forward as evaluate_forward
from ..metrics import make_validation_cases as make_validation_cases
from ..metrics import training_box as training_box

__all__ = [
    "BENCHMARK_SECTIONS",
    "BENCHMARK_SYSTEMS",
    "BenchmarkResult",
    "build_report",
    "ray_ensemble_fitter",
    "run_real_benchmark",
    "CaseResult",
    "EXECUTORS",
    "ForwardEvaluation",
    "HORIZONS",
    "Job",
    "KEY_COLUMNS",
    "PAPER_SNR_DB",
    "QUICK_SNR_DB",
    "ResultsStore",
    "RunSettings",
    "Sweep",
    "SweepInterrupted",
    "SweepReport",
    "VALIDATION_RANGES",
    "VALUE_COLUMNS",
    "ValidationCase",
    "ValidationSet",
    "cached_validation_cases",
    "dataset_seed",
    "docs_tables",
    "fill_table_markers",
    "zoo_coverage_tables",
    "selection_tables",
    "units_table",
    "parity_table",
    "gated_rows",
    "coverage_table",
    "per_curve_table",
    "default_fit_options",
    "evaluate_forward",
    "job_key",
    "make_validation_cases",
    "paper_grid",
    "parse_name_list",
    "parse_snr_list",
    "plan_units",
    "quick_grid",
    "run_benchmark",
    "run_sweep",
    "run_unit",
    "training_box",
]
