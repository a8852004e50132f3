"""The paper's studies, reproduced with execution in simulation.

- :mod:`~clfd_bench.studies.start_robustness`: predictions from novel start positions.
- :mod:`~clfd_bench.studies.task_order`: the CL metrics under task orders 0, 1, 2.
- :mod:`~clfd_bench.studies.sensitivity`: robustness to the regularisation hyperparameters.
- :mod:`~clfd_bench.studies.inference_timing`: hypernetwork → NODE generation, a NODE step, a
  1000-step trajectory.
  What is timed: :mod:`~clfd_bench.studies.inference_timing_measure`; the tables:
  :mod:`~clfd_bench.studies.inference_timing_report`.
- :mod:`~clfd_bench.studies.task_time`: training time per task as tasks accrue.
- :mod:`~clfd_bench.studies.loops`: loops with and without a time input (self-crossings,
  DTW, execution per task).
- :mod:`~clfd_bench.studies.paper_grid` / :mod:`~clfd_bench.studies.paper_tables`: the full
  paper grid and its tables next to the paper's own numbers
  (:mod:`~clfd_bench.metrics.paper_numbers`).

Each has a command: ``clfd-bench study start|order|sensitivity|timing|tasktime|loops`` and
``clfd-bench paper``.
"""
