"""Above the core, below PyBullet: what the model is checked against and how it is chosen.

closed_forms (every closed form once, with the reference set-ups that realise them) ·
measures (every error measure: frequencies, amplitudes, block-mean forces, shapes) ·
study (the paper's table) · resolve (the automatic choice of n, integrator and dt).
"""
