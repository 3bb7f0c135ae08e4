/* Every denoiser and filter the library offers, in the order tools list
 * them: the op types marked with EW_REGISTER_OP, which the build collects
 * into ew_op_list.h (cmake/ew_op_registry.cmake).
 *
 * The array is weak so that a test build can link a registry with one
 * method more (tests/gain: a method added as docs/adding-a-method.md says,
 * to check it reaches every front): that build compiles this file against
 * its own list with EW_REGISTRY_STRONG, and its definition wins. */
#include "src/op.h"

#include "ew_op_list.h"

#define EW_OP_DECLARE(TYPE) extern const ew_op_type TYPE;
EW_OP_LIST(EW_OP_DECLARE)

#ifdef EW_REGISTRY_STRONG
#define EW_REGISTRY_LINKAGE
#else
#define EW_REGISTRY_LINKAGE __attribute__((weak))
#endif

#define EW_OP_ADDRESS(TYPE) &TYPE,
EW_REGISTRY_LINKAGE const ew_op_type *const ew_op_types[] = {EW_OP_LIST(EW_OP_ADDRESS) NULL};
