"""The PyBullet coupling: a world with ground and obstacles, cables as driven spheres."""
