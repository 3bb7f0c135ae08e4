/*
 * cpu_simd_end.h — closes one instruction set's block of cpu_conv.c: every
 * macro the SIMD bodies read, so the next block defines its own.
 */
#undef EW_V
#undef EW_MM
#undef EW_VLOAD
#undef EW_VSTORE
#undef EW_VSET1
#undef EW_VZERO
#undef EW_VFMA
#undef EW_VADD
#undef EW_VSUB
#undef EW_VMUL
#undef EW_VMAX
#undef EW_VTRANS4
#undef EW_SUFFIX
#undef EW_VW
#undef EW_XB4
#undef EW_XB5
#undef EW_WXB
#undef EW_WCB
#undef EW_NO_DWEIGHT
