"""The playing surface the net's knots stop on: a one-sided, inelastic, frictionless contact.

After every step of every knot kernel (csr, grid, implicit), a free knot below TABLE_Z is put
back on it and loses its downward velocity: the projection cloth solvers apply against
colliders. A hanging net's hem swings down onto the table when struck low; a real net cannot
pass through it.
"""

TABLE_Z = 0.0  # m: the playing surface (the frame's origin is its centre, z up)
