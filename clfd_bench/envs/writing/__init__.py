"""Writing environments: HelloWorld letters, the HelloWorld text, and LASA shapes, drawn with a
spring-loaded pen on a writing board. The scene and every constant are in `tasks/writing.xml`
and `tasks/writing.toml`; the per-task success tolerances, derived from the demonstrations by
`clfd_bench.envs.writing.derive`, in `tasks/writing_tolerances.toml`.

Success is judged on the ink, as an observer would (`judge_shape`): the paper's summed DTW,
plus the shape (Hausdorff distance and arc-length coverage against the target demo), the end
point, and the timing (the pen does not rest at its end point for most of the episode).

One module per concept: `spec` (the scene's constants, the specs and the tolerances), `judge`
(the ink judged, a pure function), `board` (the pen, the board, the ink: `WritingBase`),
`shapes` (a letter, a LASA shape), `text` (the HelloWorld text) and `derive` (build time only:
the tolerances derived from the demonstrations, `eval/make_task_specs.py`). Every public name is
importable from `clfd_bench.envs.writing` (the envs' entry points are
`clfd_bench.envs.writing:<Env>`).
"""

from clfd_bench.envs.writing.board import WritingBase, framing_camera, min_jerk
from clfd_bench.envs.writing.judge import SHAPE_CHECKS, dwell_fraction, ink_strokes, judge_shape
from clfd_bench.envs.writing.shapes import HelloWorldLetterEnv, LasaShapeEnv, ShapeEnv
from clfd_bench.envs.writing.spec import (
    CAMERA_ELEVATION,
    DECIDE_BATCH,
    DECIDE_MARGIN,
    PEN_DOWN_LIFT,
    PHYSICS_DT,
    SETTLE_STEPS,
    TOLERANCE_KEYS,
    WRITING_SPEC_FILE,
    ShapeTolerances,
    WritingSpec,
    load_tolerances,
    load_writing_spec,
    writing_settle_s,
)
from clfd_bench.envs.writing.text import HelloWorldTextEnv

__all__ = ["CAMERA_ELEVATION", "DECIDE_BATCH", "DECIDE_MARGIN", "PEN_DOWN_LIFT", "PHYSICS_DT",
           "SETTLE_STEPS", "SHAPE_CHECKS", "TOLERANCE_KEYS", "WRITING_SPEC_FILE",
           "HelloWorldLetterEnv", "HelloWorldTextEnv", "LasaShapeEnv", "ShapeEnv",
           "ShapeTolerances", "WritingBase", "WritingSpec", "dwell_fraction", "framing_camera",
           "ink_strokes", "judge_shape", "load_tolerances", "load_writing_spec", "min_jerk",
           "writing_settle_s"]
