#version 450
// Near tier, box proxy (measured alternative, CONTRACT.md §3.10): instance i draws the 12
// triangles of sprite i's proxy box. Only front faces survive culling, so each covered pixel
// runs the kernel once. The box's perspective projection can miss outline pixels that the
// sprite's parallel rays reach (eye rays diverge at close range), hence not the default.
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"

layout(std430, set = 0, binding = NEAR_BINDING_BOXES) readonly buffer Boxes {
    NearBox vtBoxes[];
};

// Corner k is (k & 1, k >> 1 & 1, k >> 2) in voxel space. Every face is wound counter-
// clockwise seen from outside. Voxel -> world is a proper rotation (positive scale) and the
// image is an unmirrored view, so faces towards the eye stay counter-clockwise in the image:
// the pipeline uses VK_FRONT_FACE_COUNTER_CLOCKWISE with back-face culling.
const int kBoxTriangles[36] = int[36](
    0, 4, 6, 0, 6, 2,  // -x
    1, 3, 7, 1, 7, 5,  // +x
    0, 1, 5, 0, 5, 4,  // -y
    2, 6, 7, 2, 7, 3,  // +y
    0, 2, 3, 0, 3, 1,  // -z
    4, 5, 7, 4, 7, 6); // +z

layout(std430, set = 0, binding = NEAR_BINDING_CELL_BASES) readonly buffer CellBases {
    uint vtCellBases[];
};

layout(location = 0) flat out uint vInstance;

void main() {
    gl_Position = vtBoxes[gl_InstanceIndex].corner[kBoxTriangles[gl_VertexIndex]];
    vInstance = uint(gl_InstanceIndex);
    // Cell-rate sprites are drawn by the compute passes: outside the clip volume, no fragments.
    if (vtCellBases[gl_InstanceIndex] != NEAR_NO_CELLS) gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
}
