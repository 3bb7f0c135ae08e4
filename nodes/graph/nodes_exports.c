/* The shared libedgewise_nodes: everything comes from edgewise_nodes_static
 * (linked whole); only what nodes.h marks EW_NODES_API is exported. */
#include "edgewise/nodes.h"
typedef int ew_nodes_exports_unused;
