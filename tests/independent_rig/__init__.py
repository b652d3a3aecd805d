"""An independent simulator of the rig and the out-of-library acceptance of ``ehas diagnose`` (issue 20, point 5).

Plain NumPy/SciPy, written from docs/ (reference-model.md, rig.md,
measurement-format.md, model-file.md); it imports nothing of ehas
(``test_independent_generator.py`` checks it).  Its laws are deliberate twins of
the reference model's: another engine, so that a diagnosis is judged on data
its own code did not make.  docs/independent-generator.md describes it.
"""
