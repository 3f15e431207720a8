// Anchor translation unit for brdf.h (keeps the library non-empty before models land).
#include "shading/brdf.h"
