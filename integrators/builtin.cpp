// The built-in integrators (every file in integrators/) form one plugin
// linked into the program; it exports the same entry point a third-party
// plugin does, and the core registers it through the same loader.
#include <obscura/plugin.h>

OBSCURA_PLUGIN_ENTRY("obscura built-ins")
