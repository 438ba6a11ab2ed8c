"""The fits of the method, one module per sensor or method: ``magnetometer`` (eqs. 17-24),
``alignment`` (eqs. 25-31), ``accelerometer`` (eq. 32), ``gyroscope`` (eqs. 33-36), and the
partial protocols ``ferraris`` and ``posetopose``; ``orientations`` judges what a set of static
poses lets the cube fit determine.
"""
