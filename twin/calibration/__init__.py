"""The calibration pipeline: split, model, problem, solve, assess (:mod:`.pipeline`); what a
result predicts (:mod:`.predict`), how far it is from a truth (:mod:`.accuracy`), the choice of
error groups (:mod:`.selection`), why a fit misses (:mod:`.diagnosis`) and what a measurement
set identifies (:mod:`.assessment`).
"""
