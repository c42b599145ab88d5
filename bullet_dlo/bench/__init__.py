"""Benchmarks: scenarios (S1-S4 with their references) · sweeps (work-precision, stability map,
scaling, in the core and in Bullet with contact on) · plots · peers (PyElastica and MuJoCo on S1/S2;
runners in peer_pyelastica, peer_mujoco)."""
