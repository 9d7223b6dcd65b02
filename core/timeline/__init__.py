"""The built-in rerun timeline: a plugin that records run events to an ``.rrd`` file.

Registered through the ``msrr.plugins`` entry point ``timeline``
(:mod:`msrr.core.timeline.plugin`), exactly like a third-party plugin. The writer
is :class:`msrr.core.timeline.recorder.TimelineRecorder`; recordings are read back
with :mod:`msrr.core.timeline.readback`.

This package imports the rerun SDK only when a run records or a recording is read
(rerun takes about 0.3 s to import; every ``platform`` command, ``--help`` included,
loads this plugin), so neither the recorder nor the blueprint is imported here.
"""

from .readback import (
           Recording,
           RecordingSummary,
           Row,
           read_recording,
           read_rows,
           summarize_recording,
)

__all__ = ["Recording", "RecordingSummary", "Row", "read_recording", "read_rows",
           "summarize_recording"]
