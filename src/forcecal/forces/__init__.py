"""Forces from reactions and inertia (METHOD.md sections 2, 3 steps 4-6, 6 and 7): the sensors'
generalized coordinates, the force solve, the steady and the any-drive estimators, and the
uncertainty budget of both."""
