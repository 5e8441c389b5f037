#version 450
// Near tier fragment shader: one pixel of one voxel sprite, evaluated by the shared kernel
// (core/sprite_kernel.h, the very code the CPU reference runs), so the Vulkan image equals the
// reference image bit for bit. Outputs: packed RGBA8 colour and entity id as R32_UINT (exact
// integers, no unorm conversion) and the sprite's billboard depth (reversed-Z, CONTRACT.md §3.8).
// Compiled four times: as is, with -DVT_COUNT_STEPS, which also counts voxel reads, and each
// with -DVT_FLAT_DEPTH for sprites whose proxy the host flattened to the sprite's own depth
// (NearOptions::earlyDepthTest): the rasterised depth then is the billboard depth bit for bit, so
// the shader writes none, and the depth test can run before it (early depth test) and reject a
// hidden fragment untraced. (A shader that writes memory, as the counting one, is tested late on
// llvmpipe; its image is the same.) Sprites drawn cell-rate (volumetric/near_rate.hpp) never
// reach this stage: the proxy vertex shaders collapse them, and the compute passes near_cells,
// near_cell_outline and near_splat draw them.
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"
#include "volumetric/shaders/near_voxels.h"
#include "core/sprite_kernel.h"

#include "volumetric/shaders/near_sprites.h"
layout(std430, set = 0, binding = NEAR_BINDING_PALETTES) readonly buffer Palettes {
    uint vtPalettes[];
};

layout(location = 0) flat in uint vInstance;
layout(location = 0) out uint outColor;
layout(location = 1) out uint outEntity;

void main() {
    SpriteGpu s = vtSprites[vtRecordOf[vInstance]];
    vtAtlasBase = ivec3(s.atlas.xyz);
    vtBrickBase = s.brickBase;
    uint index;
    uint face;
    uint kind = vtShadePixel(s, gl_FragCoord.xy, index, face);
#ifdef VT_COUNT_STEPS
    vtCount64(0u, vtFetches);
    vtCount64(1u, 1u);
#endif
    if (kind == VT_KIND_EMPTY) discard;
    outColor = kind == VT_KIND_SOLID ? vtLit(vtPalettes[s.atlas.w + index], vtFaceLight(s, face))
                                     : VT_OUTLINE_RGBA;
    outEntity = s.dims.w;
#ifndef VT_FLAT_DEPTH
    gl_FragDepth = s.depth;
#endif
}
