/* volk's meta-loader, compiled into the library from Debian's libvulkan-volk-dev. */
#include <volk.c>
