#define SIDE(x) old_##x
#include "side.inc"
