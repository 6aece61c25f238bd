"""wsnloc: reproducible experiments for indoor localization and tracking in WSNs.

Data flows one way: raw logs -> canonical Parquet tables -> estimates -> metrics -> report.
Each stage is a package here and can be used without Snakemake.
"""

__version__ = "0.1.0"
