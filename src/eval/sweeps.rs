//! Speed and stability sweeps: one knob at a time around the defaults, error against time
//! (speed) or against the size of a perturbation, mean and spread over seeds (stability).
