"""Force datasets: domain-randomised capture, HDF5 episodes, manifest, reader.

plan.py (an episode's parameters, stability policy) -> episode.py (running and recording one
episode) -> storage.py (episode files, manifest) -> runners.py (process pool, Ray) ->
capture.py (the coordinator); reader.py (Dataset, load_episode); quality.py (force quality).
"""
from bullet_dlo.data.capture import capture
from bullet_dlo.data.reader import Dataset, load_episode

__all__ = ["Dataset", "capture", "load_episode"]
