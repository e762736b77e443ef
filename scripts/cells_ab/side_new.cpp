#define SIDE(x) new_##x
#include "side.inc"
