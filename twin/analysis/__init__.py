"""What a fit means: residual metrics, identifiability (rank, null space, base parameters),
the motions the data cannot see (gauge), uncertainty and the Cramér–Rao bound, and the misfit
test. Pure numpy and scipy.
"""
