"""Measurement design: D-optimal poses, ports and stations (:mod:`.optimal`, pure numpy) and
the plan of a capture among candidates a sampler draws (:mod:`.planning`; the MuJoCo sampler is
passed in by the caller, never imported here).
"""
