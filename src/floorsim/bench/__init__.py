"""The test bench: render -> run estimators -> score -> paper protocols -> report, gates, sweeps.

Modules, lowest layer first (none imports one above it):

* :mod:`floorsim.bench.results`: ``results.csv`` (and the paper-000 CSVs) written and read;
* :mod:`floorsim.bench.report`: the self-contained HTML report and Markdown summary;
* :mod:`floorsim.bench.gates`: baselines and the regression gate;
* :mod:`floorsim.bench.estimators`: how the bench builds and runs estimators (a collaborator
  that tests replace);
* :mod:`floorsim.bench.protocols`: paper protocols as plugins in a registry (paper 000's
  strip runs, paper 001's line, paper 003's map and kidnap), chosen by each scene's
  ``[bench]`` table;
* :mod:`floorsim.bench.bench`: :func:`run_bench` (``floorsim bench``), the render cache,
  the estimator runner;
* :mod:`floorsim.bench.sweep`: lighting-robustness sweeps (``floorsim sweep``), locally or on Dask.
"""

from floorsim.bench.bench import BenchResult, render_cached, run_bench
from floorsim.bench.estimators import EstimatorRunner

__all__ = ["BenchResult", "EstimatorRunner", "render_cached", "run_bench"]
