"""The built-in rerun timeline: a plugin that records run events to an ``.rrd`` file.

Registered through the ``msrr.plugins`` entry point ``timeline``
(:mod:`msrr.core.timeline.plugin`), exactly like a third-party plugin.
"""

from .blueprint import build_blueprint
from .readback import RecordingSummary, summarize_recording
from .recorder import TimelineRecorder

__all__ = ["RecordingSummary", "TimelineRecorder", "build_blueprint", "summarize_recording"]
