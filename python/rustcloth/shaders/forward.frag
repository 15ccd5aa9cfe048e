#version 330 core
// Software tier, forward pass: the one-sided surfaces (floor, spheres, colliders, markers).
#include "forward_fragment.glsl"
