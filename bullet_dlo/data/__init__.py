"""Force datasets: domain-randomised capture, HDF5 episodes, manifest, reader."""
from bullet_dlo.data.capture import Dataset, capture, load_episode

__all__ = ["Dataset", "capture", "load_episode"]
