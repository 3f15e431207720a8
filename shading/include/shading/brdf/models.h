// Every analytic model class, for code that builds models by type rather than from a spec
// (make_brdf, model_spec.h). One header per model; include the one you need.
#pragma once

#include "shading/brdf/lafortune.h"
#include "shading/brdf/lambert.h"
#include "shading/brdf/microfacet.h"
#include "shading/brdf/oren_nayar.h"
#include "shading/brdf/phong_normalized.h"
#include "shading/brdf/pov_highlights.h"
#include "shading/brdf/ward.h"
