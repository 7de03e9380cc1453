// shoal_vehicle: one follower UUV process. Thin main; the app is vehicle/vehicle_app.
#include "vehicle/vehicle_app.h"

int main(int argc, char** argv) { return shoal::VehicleMain(argc, argv); }
