"""floorsim: renders the paper-000 floor rig with Mitsuba 3 and runs the test bench.

Imports floorvo, never the reverse. Mitsuba is imported only inside
:mod:`floorsim.render` (the backend), so scene files, trajectories and the bench's
bookkeeping work without it.
"""

__version__ = "0.1.0"
