// What every far pass shader (far_blit.comp, far_splat.comp) reads, and the one function that
// says what a far sprite draws at a pixel: the far blit of impostor_cache/far_blit.cpp, pixel for
// pixel. Included after core/sprite_kernel.h and far_shared.h; the including shader declares
// the planes (read-only where it only reads them).

layout(std430, set = 0, binding = FAR_BINDING_INSTANCES) readonly buffer Instances {
    FarInstanceGpu vtFar[];
};
layout(std430, set = 0, binding = FAR_BINDING_SNAPSHOTS) readonly buffer Snapshots {
    uint vtSnapshotWords[];
};
layout(std430, set = 0, binding = FAR_BINDING_PALETTES) readonly buffer FarPalettes {
    uint vtFarPalettes[];
};
layout(push_constant) uniform Push {
    FarPush vtPush; // count: tiles (far_blit.comp) or instances (far_splat.comp)
};

const uint FAR_EMPTY = 0u;
const uint FAR_SOLID0 = 1u;
const uint FAR_OUTLINE = 7u;

// The colour far instance f (its sprite s, read once by the caller) draws at pixel centre pc:
// the near lattice cell (vtPixelCell, dither included), the snapshot cell under that cell's
// centre (the SnapshotCellMap, in double like the CPU's), and the cell's colour (vtLit of the
// palette entry by the entered face's light, or the outline). False where it draws nothing.
bool farPixelColour(uint f, VT_IN(SpriteGpu) s, vec2 pc, out uint colour) {
    colour = 0u;
    ivec2 cell;
    if (!vtPixelCell(s, pc, cell)) return false;
    precise double u = vtFar[f].u0 + vtFar[f].ui * double(cell.x) + vtFar[f].uj * double(cell.y);
    precise double v = vtFar[f].v0 + vtFar[f].vi * double(cell.x) + vtFar[f].vj * double(cell.y);
    int si = int(floor(u)) - int(vtFar[f].snap.w);
    int sj = int(floor(v)) - vtFar[f].extra.x;
    if (si < 0 || si >= int(vtFar[f].snap.y) || sj < 0 || sj >= int(vtFar[f].snap.z)) return false;
    uint slot = uint(sj) * vtFar[f].snap.y + uint(si);
    uint bits = (vtSnapshotWords[vtFar[f].snap.x + (slot >> 1)] >> ((slot & 1u) * 16u)) & 0xFFFFu;
    uint code = bits >> 8;
    if (code == FAR_EMPTY) return false;
    colour = code == FAR_OUTLINE
                 ? VT_OUTLINE_RGBA
                 : vtLit(vtFarPalettes[uint(vtFar[f].extra.y) + (bits & 255u)],
                         vtFaceLight(s, code - FAR_SOLID0));
    return true;
}
