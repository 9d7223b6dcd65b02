"""A third-party msrr robot described only: wheeled four-face cubes, run in MuJoCo."""
