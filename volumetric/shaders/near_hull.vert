#version 450
// Near tier, hull proxy (the default, see near_shared.h NearHull): instance i draws the
// convex silhouette polygon of sprite i as a fan, triangle t = (0, t + 1, t + 2); triangles past
// the polygon's corner count collapse onto corner 0 and produce no fragments. The polygon covers
// every pixel whose kernel outcome can be non-empty, with two pixels to spare, so coverage rules
// never decide a drawn pixel (as with the quad, but without the quad's corners and extra cells).
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"

layout(std430, set = 0, binding = NEAR_BINDING_HULLS) readonly buffer Hulls {
    NearHull vtHulls[];
};

layout(std430, set = 0, binding = NEAR_BINDING_CELL_BASES) readonly buffer CellBases {
    uint vtCellBases[];
};

layout(location = 0) flat out uint vInstance;

void main() {
    uint t = uint(gl_VertexIndex) / 3u;
    uint k = uint(gl_VertexIndex) % 3u;
    uint count = vtHulls[gl_InstanceIndex].count;
    uint corner = (k == 0u || t + 2u >= count) ? 0u : t + k;
    gl_Position = vtHulls[gl_InstanceIndex].corner[corner];
    vInstance = uint(gl_InstanceIndex);
    // Cell-rate sprites are drawn by the compute passes: outside the clip volume, no fragments.
    if (vtCellBases[gl_InstanceIndex] != NEAR_NO_CELLS) gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
}
