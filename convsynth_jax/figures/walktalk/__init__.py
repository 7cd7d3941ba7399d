"""Figures of the Walk the Talk evaluation."""
from .evaluation import (
    elbow_bend_figure,
    gait_phase_panel,
    gait_phases_figure,
    peak_phase_figure,
    splice_contact_sheet_figure,
)

__all__ = ["elbow_bend_figure", "gait_phase_panel", "gait_phases_figure", "peak_phase_figure",
           "splice_contact_sheet_figure"]
