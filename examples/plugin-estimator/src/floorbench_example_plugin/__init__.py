"""Example floorvo estimator plugin (see README.md): :class:`~floorbench_example_plugin.fft_shift.FftShift`."""

__version__ = "0.1.0"
