//! ParaView `.pvd` time series (in progress).
