"""Layer 0, the core: errors, units, geometry, the pose-graph model and the timed-pose trajectory.

Nothing here imports another part of the studio, reads or writes files, or imports a heavy library.
"""
