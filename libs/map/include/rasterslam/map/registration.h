// Registering classes with MRPT's RTTI when a library or plugin module loads.
#pragma once

/** Use instead of MRPT_INITIALIZER, after the IMPLEMENTS_* lines of the classes it registers:
 *  RASTERSLAM_REGISTER_CLASSES(register_ns_Name) { mrpt::rtti::registerClass(CLASS_ID(ns::Name)); }
 *  The body runs from an ordinary static object of this file, so after the classes' runtime
 *  ids above it are initialized. MRPT_INITIALIZER uses a constructor attribute whose order
 *  relative to them is unspecified: GCC happens to run it after them, clang before (the
 *  classes were then never registered, and no plugin could be created). */
#define RASTERSLAM_REGISTER_CLASSES(f) \
	static void f();                   \
	namespace                          \
	{                                  \
	struct f##_at_load                 \
	{                                  \
		f##_at_load() { f(); }         \
	} f##_instance;                    \
	}                                  \
	static void f()
