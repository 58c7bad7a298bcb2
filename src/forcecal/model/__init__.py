"""The spatial response model (METHOD.md sections 2 and 3, steps 1-3): a scan's deflection
shapes, the smooth basis they are fitted in, the relaxation shapes and the mass couplings; for
a steady drive a harmonic model, for a broadband scan a model over its band."""
