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
* :mod:`floorsim.bench.material_calibration`: the motion suite's per-material scale
  calibration: the spin in place over a material, and the straight run's calibration against
  the one with the yaw (straight run and spin), with why the yaw's is missing;
* :mod:`floorsim.bench.search`: the pure core of studies: failure criteria, breaking-point
  brackets by bisection, confidence intervals;
* :mod:`floorsim.bench.study`: the study (sweep) file format and the record of a study;
* :mod:`floorsim.bench.sweep_report`: a study's report: curves with their spread, the
  search, envelopes and margins;
* :mod:`floorsim.bench.sweep`: lighting-robustness studies (``floorsim sweep``): grids and
  breaking-point searches, locally or on Dask.
"""

from floorsim.bench.bench import BenchResult, render_cached, run_bench
from floorsim.bench.estimators import EstimatorRunner

__all__ = ["BenchResult", "EstimatorRunner", "render_cached", "run_bench"]
