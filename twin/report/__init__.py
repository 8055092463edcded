"""What a user reads: the text report of a calibration (:mod:`.text`) and its figures
(:mod:`.plots`, matplotlib).
"""
