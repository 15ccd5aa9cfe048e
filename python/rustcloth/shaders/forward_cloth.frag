#version 330 core
// Software tier, forward pass: the cloth, both of whose sides show.
#define TWO_SIDED
#include "forward_fragment.glsl"
