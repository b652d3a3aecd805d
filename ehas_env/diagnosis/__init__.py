"""The diagnosis: a model against a campaign, what it misses, in physical words (``ehas diagnose``).

Above :mod:`ehas_env.measurement` (the campaign readers, the replay of logs, the verdict's measure), one module per
part of the pipeline (docs/diagnosis-pipeline.md draws it):

====================  =================================================================================
module                what it holds
====================  =================================================================================
``pipeline``          the stages in order (``STAGES``, ``run_stages``, ``diagnose_open``) and the stages of
                      the final model: measured inputs, states, measure, no_worse, per-run parameters,
                      verdict, proposal, alternatives
``search``            the shared state of a diagnosis (``Search``) and the first stages: data, library,
                      hypotheses (rounds of candidates, each judged)
``candidates``        a candidate effect screened, refined and ranked on the library's null model
``fitting``           the fit of a model's free numbers (least squares on the log cost), intervals
``honesty``           the rules a kept term or hypothesis must pass
``keeping``           the gates of a kept effect (sane, validation, the same on groups of runs)
``states``            the state stage: every generic augmentation (followers at every signal place, static
                      blocks at every reading, links, hoses, play; :mod:`ehas_env.physics.augment`) tried
``measured_inputs``   a logged quantity taken as an input of the model
``proposal``          the missing term at a place of the model, screened on its linearisation, fitted inside
``naming``            the flexible term named by physical forms
``alternatives``      a kept effect's confusable rivals
``drift``             parameters per run and the recorded conditions they follow
``disturbances``      lines in the logs no harmonic of the test explains
``hypothesis_file``   a hypothesis written by the user, read as data
``experiment_design`` the test plan that would tell rivals apart
``health``            a rig's parameters over months of campaigns
``acceptance``        the acceptance of a diagnosis on campaigns of the package's own generator
``book_rig_loads``    the book rig's peak loads analysed
``plots``             the diagnosis' figures
====================  =================================================================================
"""
