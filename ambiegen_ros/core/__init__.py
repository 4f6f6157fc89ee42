"""ROS-free search engine: scenario representation, operators, diversity, search loop, run files."""
