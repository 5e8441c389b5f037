#pragma once
// Every shared test helper at once. A test includes the focused headers it uses; this umbrella
// is for suites that want them all:
//   source_tree.hpp       sourcePath, the bundled .vox models
//   test_models.hpp       models built in code (solidBox, markedBar)
//   view_sweeps.hpp       sweep directions, viewToward, viewAlong at an exact magnification
//   closed_form.hpp       the independent closed-form sprite: cells, lighting, mismatch count
//   image_checks.hpp      a reference frame, drawn pixels, describeDifference
//   hard_case_scenes.hpp  the hard cases' scenes and the marked bar's centres
//   vulkan_test_env.hpp   the shared validated NearRenderer, VulkanTest, renderBoth
#include "closed_form.hpp"
#include "hard_case_scenes.hpp"
#include "image_checks.hpp"
#include "source_tree.hpp"
#include "test_models.hpp"
#include "view_sweeps.hpp"
#include "vulkan_test_env.hpp"
