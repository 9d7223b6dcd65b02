"""A minimal third-party msrr robot plugin: hinge modules that form chains."""
