"""Episode records (``episode.json``) and the HTML episode report."""

from efficienteqa.report.episode import episode_record
from efficienteqa.report.frames import FrameCollector
from efficienteqa.report.html import write_report

__all__ = ["FrameCollector", "episode_record", "write_report"]
