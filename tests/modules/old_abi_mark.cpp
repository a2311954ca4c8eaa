// The ABI mark of a module built for plugin ABI 0: a strong definition, which the linker
// takes over the weak one plugin.h gives old_abi_rasterizer.cpp.
extern "C" int rasterslam_plugin_abi()
{
	return 0;
}
