"""ybgc: the YARP bottle generator compiler."""
__version__ = "0.1.0"
