"""Visual inspection of runs: videos (:mod:`clfd_bench.viz.video`) and rerun logs
(:mod:`clfd_bench.viz.rerun_log`). Import the submodules; nothing heavy is imported here."""
