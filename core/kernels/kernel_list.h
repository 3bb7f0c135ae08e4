/*
 * kernel_list.h — what a backend needs to expand EW_KERNEL_LIST
 * (kernels/kernel_ids.h): the headers of the kernels it lists. Only the
 * backends include it, so a change to one kernel rebuilds the backends and
 * the ops that use that kernel, not every file that calls a backend.
 */
#ifndef EW_KERNELS_KERNEL_LIST_H
#define EW_KERNELS_KERNEL_LIST_H

#include "kernels/atrous.h"
#include "kernels/kernel_ids.h"
#include "kernels/kpcn.h"
#include "kernels/mirror.h"

#endif
