#version 450
// Near tier, quad proxy (CONTRACT.md §3.10; NearProxy::Quad, the hull is the default): instance i
// draws the camera-facing quad of sprite i, whose clip-space corners core/sprite.cpp computed in
// double (SpriteSetup::quad, written by the host into the hull buffer in strip order). The
// fragment shader decides every pixel; the quad only has to cover them.
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
    gl_Position = vtHulls[gl_InstanceIndex].corner[gl_VertexIndex];
    vInstance = uint(gl_InstanceIndex);
    // Cell-rate sprites are drawn by the compute passes: outside the clip volume, no fragments.
    if (vtCellBases[gl_InstanceIndex] != NEAR_NO_CELLS) gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
}
