// The solids' depth written further from the eye than they are: the cloth lying on a solid is
// drawn as flat triangles between particles held `thickness` off its surface, and where it
// bends over an edge a triangle cuts the corner, so the edge showed through the cloth as a
// dotted line. Pushing only the depth (the pixels covered stay the same) lets cloth that is
// in front of the solid, or up to `depth_push` under its surface, win the depth test. The
// including shader declares the uniforms: view_proj, eye, depth_push (m, 0 for a surface not
// pushed).

// How much further along the view ray the depth at world point `world` (unit normal n) is
// written: depth_push back along the normal, as the ray sees it, so longer where it grazes
// the surface (a corner cut by the cloth lies further along a grazing ray), at most 4 times.
float pushed_by(vec3 world, vec3 n) {
    if (depth_push <= 0.0) return 0.0;
    return depth_push / max(abs(dot(n, normalize(world - eye))), 0.25);
}

// `clip` (the position of `world`) with the depth of the point `push` m further along the ray.
vec4 depth_pushed(vec4 clip, vec3 world, float push) {
    if (push <= 0.0) return clip;
    vec4 pushed = view_proj * vec4(world + normalize(world - eye) * push, 1.0);
    clip.z = pushed.z / pushed.w * clip.w;
    return clip;
}
