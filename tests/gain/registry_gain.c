/* The library's registry with "gain" appended: this definition of
 * ew_op_types replaces the library's own (a weak symbol) in the test
 * library libedgewise of tests/gain. */
#include "src/op.h"

extern const ew_op_type ew_filter_gain;
#define EW_EXTRA_OP_TYPES &ew_filter_gain,
#include "src/registry.c"
