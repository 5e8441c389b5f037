// The frame's sprite records, included after core/sprite_kernel.h by every near shader that reads
// them. Each place in the draw order (instance, tile, block and rank entries name places) finds
// its record through vtRecordOf: vtSprites[vtRecordOf[place]]. The host lays the records out by
// NearRecords (volumetric/near_passes.hpp): at their places (vtRecordOf[p] == p), or in the order
// the sprites were given (a store's: entity order), which the host writes reading the sprites in
// sequence.
#ifndef VOXTIER_NEAR_SPRITES_H
#define VOXTIER_NEAR_SPRITES_H

layout(std430, set = 0, binding = NEAR_BINDING_SPRITES) readonly buffer Sprites {
    SpriteGpu vtSprites[];
};
layout(std430, set = 0, binding = NEAR_BINDING_RECORD_OF) readonly buffer RecordOf {
    uint vtRecordOf[];
};

#endif
