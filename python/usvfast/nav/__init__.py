"""Navigation data: readers for field recordings (NMEA `usvfast.nav.nmea`, GPX `gpx`, ROS bags
`bags`, video `video`), and time-synchronised replay of multi-sensor recordings (`replay`,
`usvfast inspect`). Import from the submodules."""
