"""Planning a coarse-grained process: how coarse each feature kind allows, from the size
series' evidence (:mod:`engine.process.planner`)."""

from .planner import FEATURE_KINDS, FeaturePlan, Process, ProcessPlan, answer_line, plan_process

__all__ = ["FEATURE_KINDS", "FeaturePlan", "Process", "ProcessPlan", "answer_line", "plan_process"]
