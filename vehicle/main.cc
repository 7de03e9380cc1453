// shoal_vehicle: one follower UUV process. Thin main; the app is runtime/node_app.
#include "runtime/node_app.h"

int main(int argc, char** argv) { return shoal::NodeMain(argc, argv, /*leader=*/false); }
