#version 450
// Near tier, quad proxy (CONTRACT.md §3.10; NearProxy::Quad, the hull is the default): instance i draws the camera-facing quad of sprite i,
// whose clip-space corners core/sprite.cpp computed in double. The fragment shader decides
// every pixel; the quad only has to cover them.
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"

// The kernel header needs a voxel source to compile; the vertex stage never traces.
uint vtFetchVoxel(ivec3 cell);
#include "core/sprite_kernel.h"

layout(std430, set = 0, binding = NEAR_BINDING_SPRITES) readonly buffer Sprites {
    SpriteGpu vtSprites[];
};

layout(std430, set = 0, binding = NEAR_BINDING_CELL_BASES) readonly buffer CellBases {
    uint vtCellBases[];
};

layout(location = 0) flat out uint vInstance;

void main() {
    gl_Position = vtSprites[gl_InstanceIndex].quad[gl_VertexIndex];
    vInstance = uint(gl_InstanceIndex);
    // Cell-rate sprites are drawn by the compute passes: outside the clip volume, no fragments.
    if (vtCellBases[gl_InstanceIndex] != NEAR_NO_CELLS) gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
}
