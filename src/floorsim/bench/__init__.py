"""The test bench: render -> run estimators -> score -> report, regression gates.

* :mod:`floorsim.bench.bench`: :func:`run_bench` (``floorsim bench``), the render cache;
* :mod:`floorsim.bench.report`: the self-contained HTML report and Markdown summary;
* :mod:`floorsim.bench.gates`: baselines and the regression gate;
* :mod:`floorsim.bench.protocols.paper000`: paper 000's strip protocol (Figs. 8 and 9);
* :mod:`floorsim.bench.protocols.paper003`: keyframe map and relocalisation after kidnapping.
"""

from floorsim.bench.bench import BenchResult, render_cached, run_bench

__all__ = ["BenchResult", "render_cached", "run_bench"]
