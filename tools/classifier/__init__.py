"""Training the reaction classifier (paper section 2.3), as the parts of one pipeline.

Run it as `python -m tools.train_classifier` from the repository root (or `python -m reactive_anim
train`). Modules: pushes (simulated pushes on locomotion clips, labelled by core.outcome), nets (the
numpy MLP and the paper's 9-9-4 sigmoid network), export (the ONNX file, the only user of the
`onnx` package), pipeline (the steps in order and the figures), real_mocap (generalisation figures
and the real reaction captures, from ../shared/mocap where present), report (the Markdown report
beside the model).

Importing this package limits the BLAS thread pools to one before any of its modules loads numpy:
the networks' matrices are small, the simulation workers are processes, and one thread keeps the
floating-point sums in one order, so training is repeatable bit for bit.
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
