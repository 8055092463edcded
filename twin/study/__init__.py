"""Monte-Carlo studies with known ground truth, and the paper's experiment replicated.

A study is a scenario (:mod:`twin.scenario`) with a ``[study]`` table; each trial is one
seeded simulation on which every method runs on the same split. Trials run on local processes
or a Dask cluster, are appended durably to the study folder as they finish (so a run can be
interrupted and resumed), and end in the paper's Tables 6 and 7, a truth table and figures.
A check (:mod:`twin.study.check`, public as :mod:`twin.testing`) holds a study's results to the
scenario's ``[expect]`` table and, optionally, to a baseline study.

This package imports nothing on its own, so that its pure modules (the store, the statistics,
the expectations) load without the MuJoCo twin that running trials needs::

    from twin.study.definition import load_study          # StudyPlan; InputError if invalid
    from twin.study.runner import run_study         # run_trials, then write_report
    from twin.study.store import StudyStore         # the folder: results.csv, trials.jsonl
"""
