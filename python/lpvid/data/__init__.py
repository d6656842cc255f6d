"""Data: what was measured, and over what.

Modules
-------
frf
    :class:`lpvid.FrfData`: frequency-response data at frozen scheduling values.
timedata
    :class:`lpvid.TimeData`: time records along a varying scheduling trajectory.
basis
    The basis functions psi_1..psi_Nb of the scheduling dependency.
schedule
    Scheduling values: points, their range, scaled to the unit box.
measure
    Random-phase multisines and FRFs estimated from periodic records.
"""
